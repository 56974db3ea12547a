// The tracked body's pure parts (sim/study/views/vr/web/poses.js): which bodies a frame sends, its stamp on the
// runner's clock, the XR pose taken into the scene's ROS world frame; the PoseStamped's bytes (rostcp.js); and when
// the participant is in a trial (study.js). Run by node's test runner.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { WorldFrame, frameStamp, trackedBodies } from '../../sim/study/views/vr/web/poses.js';
import { decodeString, encodePoseStamped, framesIn, rosTime } from '../../sim/study/views/vr/web/rostcp.js';
import { Participant } from '../../sim/study/views/vr/web/study.js';
import { StudyTopics } from '../../sim/study/views/vr/web/topics.js';

const PROTOCOL = JSON.parse(readFileSync(new URL('../../sim/study/run/protocol.json', import.meta.url)));
const SEAT = [0.55, -0.65, 0.45]; // the scene's: the eyes' place in the world frame

// An XRPose as WebXR gives it.
function xrPose(position, orientation = [0, 0, 0, 1], emulatedPosition = false) {
  const [x, y, z] = position;
  const [qx, qy, qz, qw] = orientation;
  return { transform: { position: { x, y, z }, orientation: { x: qx, y: qy, z: qz, w: qw } }, emulatedPosition };
}

// The column-major 4x4 matrix (three.js's elements) of rotation q = [x, y, z, w] then translation t.
function matrixOf([x, y, z, w], [tx, ty, tz]) {
  return [
    1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
    2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
    2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
    tx, ty, tz, 1,
  ]; // prettier-ignore
}

function rotate([x, y, z, w], v) {
  const m = matrixOf([x, y, z, w], [0, 0, 0]);
  return [0, 1, 2].map((row) => m[row] * v[0] + m[4 + row] * v[1] + m[8 + row] * v[2]);
}

function multiply([ax, ay, az, aw], [bx, by, bz, bw]) {
  return [
    aw * bx + ax * bw + ay * bz - az * by,
    aw * by - ax * bz + ay * bw + az * bx,
    aw * bz + ax * by - ay * bx + az * bw,
    aw * bw - ax * bx - ay * by - az * bz,
  ];
}

function near(actual, expected, what, tolerance = 1e-12) {
  assert.equal(actual.length, expected.length, what);
  actual.forEach((value, k) =>
    assert.ok(Math.abs(value - expected[k]) <= tolerance, `${what}: ${actual} vs ${expected}`),
  );
}

// Quaternions q and -q are one rotation.
function sameRotation(actual, expected, what) {
  const sign = actual.reduce((sum, value, k) => sum + value * expected[k], 0) < 0 ? -1 : 1;
  near(
    actual.map((value) => sign * value),
    expected,
    what,
  );
}

// The scene's world (scene.js): rotated -pi/2 about three's x, its origin placed so that the seat is at the origin of
// the XR reference space.
const SCENE_WORLD = matrixOf([-Math.SQRT1_2, 0, 0, Math.SQRT1_2], [-SEAT[0], -SEAT[2], SEAT[1]]);

test("the scene's world: the eyes at the origin are at the seat, three's up is ROS's z, its -z ROS's y", () => {
  const world = new WorldFrame(SCENE_WORLD);
  near(world.pose(xrPose([0, 0, 0]).transform).position, SEAT, 'the eyes', 1e-15);
  near(world.pose(xrPose([0, 1, 0]).transform).position, [SEAT[0], SEAT[1], SEAT[2] + 1], 'up', 1e-15);
  near(world.pose(xrPose([0, 0, -1]).transform).position, [SEAT[0], SEAT[1] + 1, SEAT[2]], 'forward', 1e-15);
  near(world.pose(xrPose([0.2, 0, 0]).transform).position, [SEAT[0] + 0.2, SEAT[1], SEAT[2]], 'right', 1e-15);
  // a headset looking straight ahead looks along the world's y (from the seat towards the hand), its up is z
  const ahead = world.pose(xrPose([0, 0, 0]).transform).orientation;
  sameRotation(ahead, [Math.SQRT1_2, 0, 0, Math.SQRT1_2], 'ahead');
  near(rotate(ahead, [0, 0, -1]), [0, 1, 0], 'its view', 1e-15);
  near(rotate(ahead, [0, 1, 0]), [0, 0, 1], 'its up', 1e-15);
  // turned left by 90 degrees about three's up: it looks along the world's -x
  const left = world.pose(xrPose([0, 0, 0], [0, Math.SQRT1_2, 0, Math.SQRT1_2]).transform).orientation;
  near(rotate(left, [0, 0, -1]), [-1, 0, 0], 'looking left', 1e-15);
});

test('any rigid placement of the world is undone: position and orientation, each branch of the rotation', () => {
  const turns = [
    [0, 0, 0, 1],
    [1, 0, 0, 0], // half turns: the trace is -1, each of x, y, z the largest square
    [0, 1, 0, 0],
    [0, 0, 1, 0],
    [0.1, -0.7, 0.3, 0.2],
    [-0.6, 0.2, 0.5, -0.1],
  ].map((q) => q.map((value) => value / Math.hypot(...q)));
  const origin = [0.3, -1.2, 2.5];
  const bodyInWorld = [0.4, -0.1, 0.9];
  const bodyTurn = [0.2, 0.3, -0.4, 0.8].map((value) => value / Math.hypot(0.2, 0.3, -0.4, 0.8));
  for (const turn of turns) {
    const world = new WorldFrame(matrixOf(turn, origin));
    const inSpace = rotate(turn, bodyInWorld).map((value, k) => value + origin[k]);
    const pose = world.pose(xrPose(inSpace, multiply(turn, bodyTurn)).transform);
    near(pose.position, bodyInWorld, `position, world turned ${turn}`, 1e-12);
    sameRotation(pose.orientation, bodyTurn, `orientation, world turned ${turn}`);
  }
});

test('the bodies a frame sends: the head and each hand tracked in it, nothing of one that is not', () => {
  const head = xrPose([0, 0, 0]);
  const left = xrPose([-0.1, -0.3, -0.4]);
  const right = xrPose([0.1, -0.3, -0.4]);
  const names = (bodies) => bodies.map(([body]) => body);
  const all = trackedBodies(head, [
    ['right', right],
    ['left', left],
  ]);
  assert.deepEqual(all, [
    ['head', head],
    ['right_hand', right],
    ['left_hand', left],
  ]);
  // no pose, or one the runtime made up (lost tracking), is a gap: nothing is sent for it
  assert.deepEqual(names(trackedBodies(null, [['left', left]])), ['left_hand']);
  assert.deepEqual(names(trackedBodies(xrPose([0, 0, 0], [0, 0, 0, 1], true), [['left', null]])), []);
  assert.deepEqual(names(trackedBodies(head, [['right', xrPose([0, 0, 0], [0, 0, 0, 1], true)]])), ['head']);
  // no hand without a handedness, and one pose per hand
  assert.deepEqual(
    names(
      trackedBodies(head, [
        ['none', left],
        ['left', left],
        ['left', right],
      ]),
    ),
    ['head', 'left_hand'],
  );
});

test("a frame's stamp: its time on the browser's clock plus the measured offset; none before the offset", () => {
  assert.equal(frameStamp(1500.25, 1.7e12, null), null);
  assert.equal(frameStamp(1500, 1.7e12, -1.7e9 + 2), 3.5); // 1.7e9 + 1.5 on the browser's clock
  assert.ok(Math.abs(frameStamp(16.5, 1_764_000_000_000, -1_763_999_990) - 10.0165) < 1e-6);
});

test('a PoseStamped in ROS 1 bytes: Header (seq, stamp, frame_id), then position and orientation as float64', () => {
  const bytes = encodePoseStamped(7, rosTime(12.25), 'world', [0.5, -0.65, 0.45], [0, 0, Math.SQRT1_2, Math.SQRT1_2]);
  assert.equal(bytes.length, 4 + 8 + 4 + 5 + 7 * 8);
  const view = new DataView(bytes.buffer);
  assert.deepEqual(
    [view.getUint32(0, true), view.getUint32(4, true), view.getUint32(8, true), view.getUint32(12, true)],
    [7, 12, 250_000_000, 5],
  );
  assert.equal(new TextDecoder().decode(bytes.subarray(16, 21)), 'world');
  const values = [0, 1, 2, 3, 4, 5, 6].map((k) => view.getFloat64(21 + 8 * k, true));
  assert.deepEqual(values, [0.5, -0.65, 0.45, 0, 0, Math.SQRT1_2, Math.SQRT1_2]);
  assert.throws(() => encodePoseStamped(0, rosTime(1), 'world', [0, 0], [0, 0, 0, 1]), RangeError);
});

test("the participant is in a trial in its phases, not in a questionnaire's item, nor at the end", () => {
  const participant = new Participant(PROTOCOL);
  assert.equal(participant.inTrial, false); // no status yet
  const trial = { participant: 3, index: 2, total: 4, condition: 'vr', test: 1, group_paths: [] };
  for (const phase of PROTOCOL.phases.filter((phase) => phase.accepts !== 'answer')) {
    participant.onStatus({ ...trial, phase: phase.name, index: phase.name === 'done' ? 0 : 2 });
    assert.equal(participant.inTrial, phase.name !== 'done', phase.name);
  }
  // between trials a questionnaire's item has no test, and the end neither; a questionnaire is no trial's phase
  participant.onStatus({ ...trial, phase: 'questionnaire', index: 2, test: 0, scale_low: 0, scale_high: 3 });
  assert.equal(participant.inTrial, false);
  participant.onStatus({ ...trial, phase: 'questionnaire', index: 2, test: 2, scale_low: 0, scale_high: 3 });
  assert.equal(participant.inTrial, false);
  participant.onStatus({ ...trial, phase: 'done', index: 0, test: 0 });
  assert.equal(participant.inTrial, false);
});

test("frames' poses go out together, from a task after the frames, each on its body's topic, numbered by body", () => {
  // the settings as the page's server gives them (sim/study/views/vr/site.py): each topic [name, type], and the page's
  // announcement as the VR condition's pose source, its jitter not measured yet
  const entry = ({ topic, type }) => [topic, type];
  const topics = {
    joint_states: ['/panda/joint_states', 'sensor_msgs/JointState'],
    trial: entry(PROTOCOL.status),
    ...Object.fromEntries(Object.entries(PROTOCOL.inputs).map(([name, input]) => [name, entry(input)])),
    ...Object.fromEntries(Object.entries(PROTOCOL.poses.bodies).map(([body, pose]) => [body, entry(pose)])),
    tracking: ['/study/tracking', 'std_msgs/String'],
    page_clock: ['/study/page_clock', 'std_msgs/String'],
  };
  const announcement = {
    source: 'headset',
    conditions: ['vr'],
    participant: null,
    rest_s: null,
    jitter_m: {},
    calibration: null,
  };
  const settings = { topics, protocol: PROTOCOL, pose_source: announcement };
  const study = new StudyTopics(settings, 'ws://nowhere/ros', {});
  // the announcement's topic is advertised latched, the others not; the endpoint holds a second of each body's poses
  // for ROS subscribers that fall behind, and rospy's usual 10 of the others
  assert.deepEqual(study.connection.publishers.get('/study/tracking'), ['std_msgs/String', true, 10]);
  for (const pose of Object.values(PROTOCOL.poses.bodies)) {
    assert.deepEqual(study.connection.publishers.get(pose.topic), [pose.type, false, 120]);
  }
  const messages = [];
  study.connection._send = (bytes) => messages.push(bytes); // no socket: what would be sent
  const scheduled = [];
  study.schedule = (send, ms) => scheduled.push([send, ms]); // no timer: the test sends when it wants
  const head = { position: [0.55, -0.65, 0.45], orientation: [Math.SQRT1_2, 0, 0, Math.SQRT1_2] };
  const hand = { position: [0.5, -0.4, 0.2], orientation: [0, 0, 0, 1] };
  assert.equal(study.sendPoses(10.5, [['head', head]], 'vr'), false); // not connected: nothing sent, nothing counted
  assert.deepEqual(study.posesSent, { head: 0, left_hand: 0, right_hand: 0 });
  study.connection.connected = true;
  assert.equal(
    study.sendPoses(
      10.5,
      [
        ['head', head],
        ['right_hand', hand],
      ],
      'vr',
    ),
    true,
  );
  assert.equal(study.sendPoses(10.52, [['head', head]], 'vr'), true);
  // two frames' poses, queued: one send is scheduled, after the batch's time, and nothing has gone yet
  assert.equal(messages.length, 0);
  assert.deepEqual(
    scheduled.map(([, ms]) => ms),
    [50],
  );
  scheduled.shift()[0]();
  assert.equal(messages.length, 1);
  // the connection's first send opens with the announcement, then the poses in their frames' order
  const [said, ...sent] = framesIn(messages[0]);
  assert.deepEqual([said[0], JSON.parse(decodeString(said[1]))], ['/study/tracking', announcement]);
  assert.deepEqual(
    sent.map(([topic]) => topic),
    [PROTOCOL.poses.bodies.head.topic, PROTOCOL.poses.bodies.right_hand.topic, PROTOCOL.poses.bodies.head.topic],
  );
  const frameId = PROTOCOL.poses.frame_id;
  assert.deepEqual([...sent[1][1]], [...encodePoseStamped(0, rosTime(10.5), frameId, hand.position, hand.orientation)]);
  assert.deepEqual(
    [...sent[2][1]],
    [...encodePoseStamped(1, rosTime(10.52), frameId, head.position, head.orientation)],
  );
  assert.deepEqual(study.posesSent, { head: 2, left_hand: 0, right_hand: 1 });
  // the next frame schedules the next send; a frame without tracked bodies queues nothing and schedules nothing
  assert.equal(study.sendPoses(10.54, [], 'vr'), true);
  assert.equal(scheduled.length, 0);
  study.sendPoses(10.56, [['left_hand', hand]], 'vr');
  assert.equal(scheduled.length, 1);
  scheduled.shift()[0]();
  assert.equal(messages.length, 2);
  assert.deepEqual(
    framesIn(messages[1]).map(([topic]) => topic),
    [PROTOCOL.poses.bodies.left_hand.topic],
  ); // announced once a connection
  // connected again (the endpoint may have started again, its latched announcement lost): announced again
  study.connection.onState('connected');
  study.sendPoses(10.58, [['head', head]], 'vr');
  scheduled.shift()[0]();
  assert.deepEqual(
    framesIn(messages[2]).map(([topic]) => topic),
    ['/study/tracking', PROTOCOL.poses.bodies.head.topic],
  );
  // a reality trial's poses: the page does not track reality (another tracker does), so it sends none
  assert.equal(study.tracks('reality'), false);
  assert.equal(study.sendPoses(10.6, [['head', head]], 'reality'), false);
  assert.equal(scheduled.length, 0);
  assert.deepEqual(study.posesSent, { head: 3, left_hand: 1, right_hand: 1 });
  // the rest is over: the announcement goes out again with each body's jitter, behind the poses queued before it
  study.sendPoses(10.62, [['head', head]], 'vr');
  study.measured(3, { head: 0.0002, left_hand: null, right_hand: 0.0005 });
  scheduled.shift()[0]();
  const [pose, again] = framesIn(messages[3]);
  assert.equal(pose[0], PROTOCOL.poses.bodies.head.topic);
  assert.deepEqual(
    [again[0], JSON.parse(decodeString(again[1]))],
    [
      '/study/tracking',
      { ...announcement, rest_s: 3, jitter_m: { head: 0.0002, left_hand: null, right_hand: 0.0005 } },
    ],
  );
  // and with every later connection's first poses
  study.connection.onState('connected');
  study.sendPoses(10.64, [['head', head]], 'vr');
  scheduled.shift()[0]();
  assert.equal(JSON.parse(decodeString(framesIn(messages[4])[0][1])).rest_s, 3);
  // measured while not connected: nothing goes out until the next connection's first poses
  study.connection.connected = false;
  study.measured(3, { head: 0.0001, left_hand: null, right_hand: null });
  assert.equal(scheduled.length, 0);
});

test("the page announces its clock's estimate after each ping answer that gave a sample, named by its stop source", () => {
  const topics = {
    joint_states: ['/panda/joint_states', 'sensor_msgs/JointState'],
    trial: [PROTOCOL.status.topic, PROTOCOL.status.type],
    ...Object.fromEntries(Object.entries(PROTOCOL.inputs).map(([name, input]) => [name, [input.topic, input.type]])),
    ...Object.fromEntries(Object.entries(PROTOCOL.poses.bodies).map(([body, pose]) => [body, [pose.topic, pose.type]])),
    tracking: ['/study/tracking', 'std_msgs/String'],
    page_clock: ['/study/page_clock', 'std_msgs/String'],
  };
  const study = new StudyTopics(
    { topics, protocol: PROTOCOL, pose_source: null, stop_source: 'vr_trigger' },
    'ws://x',
    {},
  );
  const connection = study.connection;
  assert.deepEqual(connection.publishers.get('/study/page_clock'), ['std_msgs/String', false, 10]);
  const messages = [];
  connection._send = (bytes) => messages.push(bytes);
  connection.connected = true;
  let now = 1_000_000;
  connection.clockMs = () => now;
  const answer = (requestTime, sentAt, rosTime) => {
    connection.pings.set(requestTime, sentAt);
    connection._system('__ping_response', { request_time: requestTime, ros_time: rosTime });
  };
  answer('a', now - 0.01, 0); // ROS time not started: no sample, nothing announced
  assert.equal(messages.length, 0);
  now += 1000;
  answer('b', now - 8, 500.0); // 8 ms round trip: ROS time 500 s at its middle, browser 1000.996 s
  now += 2000;
  answer('c', now - 30, 502.0); // slower, and within both round trips: the estimate keeps the quickest
  const said = messages.map((bytes) => {
    const [[topic, payload]] = framesIn(bytes);
    return [topic, JSON.parse(decodeString(payload))];
  });
  assert.deepEqual(
    said.map(([topic, clock]) => [topic, clock.source, clock.round_trip, clock.samples]),
    [
      ['/study/page_clock', 'vr_trigger', 0.008, 1],
      ['/study/page_clock', 'vr_trigger', 0.008, 2],
    ],
  );
  const last = said[1][1];
  assert.ok(Math.abs(last.offset - (500.0 - 1000.996)) < 1e-9, last.offset);
  assert.equal(last.applied, last.offset); // nothing to slew: stamps on the estimate
});
