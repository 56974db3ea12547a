// The page's side of the study over ROS, through the endpoint's client (connection.js): the robot's joint states and
// the trial's status in, the participant's answers and tracked body (poses.js) out, on the topics of the settings.
// The page tracks the conditions its settings name (`vr --pose-conditions`, the VR condition by default) and sends
// poses only in their trials; it announces itself as their pose source (latched), with its bodies' jitter once the
// rest at the session's start has measured it (rest.js), so that the runner names the condition's tracker as it does
// a tracker relay's: with its first poses on each connection, and again when the rest ends.
import { RosConnection } from './connection.js';
import { stopPayload } from './presses.js';
import {
  EMPTY,
  decodeJointState,
  decodeString,
  encodeFloat32,
  encodePoseStamped,
  encodeString,
  rosTime,
} from './rostcp.js';

// ms the poses wait to go out together. One WebSocket send took some 0.2 ms of the page's frame in Chromium (bench/
// vr_frame_bench.py), twenty times what encoding a frame's poses takes, and within the frame it is time the headset
// waits for; sent in batches from their own task, they leave the frame. The runner waits for an approach's last poses
// far longer than this (RunnerOptions.pose_grace).
const POSE_BATCH_MS = 50;
// The poses the endpoint holds per body for ROS subscribers that fall behind (the runner, the session's bag): a second
// at a Quest's highest refresh rate. With rospy's usual 10, a recorder starved of CPU for a few of the batches above
// lost a head pose the bag must hold (a busy machine, the emulated Quest's test).
const POSE_QUEUE_SIZE = 120;

export class StudyTopics {
  // url: the endpoint's WebSocket (through this page's server); onJoints(jointState), onStatus(trial status object).
  constructor(settings, url, { onJoints, onStatus }) {
    this.settings = settings;
    this.state = 'connecting'; // what the connection is doing, for the panel
    this.connection = new RosConnection(url, (state) => {
      this.state = state;
      if (state === 'connected') this.announced = false; // an endpoint started again has lost the latched one
    });
    // the page's announcement as a pose source (the settings', the server's shape: source, conditions, jitter_m,
    // rest_s, calibration), or null when it tracks no condition; jitter_m and rest_s are filled by the rest
    this.announcement = settings.pose_source;
    this.announced = false; // it has gone out on this connection
    this.sent = []; // the answers published: [input, value], oldest first
    const topics = settings.topics;
    this.connection.subscribe(topics.joint_states[0], topics.joint_states[1], (payload) => {
      onJoints(decodeJointState(payload));
    });
    this.connection.subscribe(topics.trial[0], topics.trial[1], (payload) => {
      onStatus(JSON.parse(decodeString(payload)));
    });
    for (const name of Object.keys(settings.protocol.inputs)) this.connection.advertise(...topics[name]);
    this.poseFrame = settings.protocol.poses.frame_id;
    this.posesSent = {}; // body -> poses published, which is the next one's seq
    this.pendingPoses = []; // [topic, payload] queued for the next send (sendPoses)
    this.flushScheduled = false;
    this.schedule = (send, ms) => setTimeout(send, ms); // the node tests run it themselves
    for (const body of Object.keys(settings.protocol.poses.bodies)) {
      this.connection.advertise(...topics[body], false, POSE_QUEUE_SIZE);
      this.posesSent[body] = 0;
    }
    this.connection.advertise(...topics.tracking, true);
    this.connection.announceClock(...topics.page_clock, settings.stop_source); // the runner judges its stamps by it
  }

  open() {
    this.connection.open();
  }

  get connected() {
    return this.connection.connected;
  }

  // ROS time (s) at atMs on this browser's clock (connection.js's browserClockMs; now by default), or null before
  // the endpoint has answered a ping.
  rosNow(atMs = undefined) {
    return this.connection.rosNow(atMs);
  }

  // ROS time minus this browser's clock (s), or null before the endpoint has answered a ping.
  get clockOffset() {
    return this.connection.clockOffset;
  }

  // Whether the page tracks the trials of `condition` (sends their poses).
  tracks(condition) {
    return Boolean(this.announcement) && this.announcement.conditions.includes(condition);
  }

  // The rest is over: each body's jitter (m, null: not measured) over restSeconds goes into the announcement, which
  // goes out again (the runner takes the latest): queued behind any poses, and an announcement of before, waiting.
  measured(restSeconds, jitters) {
    if (!this.announcement) return;
    this.announcement = { ...this.announcement, rest_s: restSeconds, jitter_m: jitters };
    this.announced = false;
    if (this.connected) this.announce();
  }

  announce() {
    this.pendingPoses.push([this.settings.topics.tracking[0], encodeString(JSON.stringify(this.announcement))]);
    this.announced = true;
    this.scheduleFlush();
  }

  scheduleFlush() {
    if (this.pendingPoses.length > 0 && !this.flushScheduled) {
      this.flushScheduled = true;
      this.schedule(() => this.flushPoses(), POSE_BATCH_MS);
    }
  }

  // Publish the bodies' poses ([body, {position, orientation}] in the world frame, poses.js) of one frame, stamped
  // with its time (s of ROS time), each on its body's topic; false when not connected. They are queued, numbered by
  // body, and go out with the other frames' of POSE_BATCH_MS in one send, from a task of its own after the frame;
  // the first poses on a connection go after the page's announcement as their pose source. A trial of a condition
  // the page does not track sends nothing (false).
  sendPoses(stamp, bodies, condition) {
    if (!this.connected || !this.tracks(condition)) return false;
    if (!this.announced && bodies.length > 0) this.announce();
    const time = rosTime(stamp);
    for (const [body, pose] of bodies) {
      const payload = encodePoseStamped(this.posesSent[body], time, this.poseFrame, pose.position, pose.orientation);
      this.pendingPoses.push([this.settings.topics[body][0], payload]);
      this.posesSent[body] += 1; // the next one's seq
    }
    this.scheduleFlush();
    return true;
  }

  // Send the queued poses in one message. A connection lost since they were queued loses them, as it loses anything
  // published while it is down: their seqs say so in the bag.
  flushPoses() {
    this.flushScheduled = false;
    const messages = this.pendingPoses;
    this.pendingPoses = [];
    if (messages.length > 0) this.connection.publishAll(messages);
  }

  // Publish a participant's answer ([input, value], study.js), if any, on its input's topic; a stop with its input
  // delay (s, or null when not measured), which goes in the Header's seq (presses.js).
  send(action, inputDelay = null) {
    if (!action) return;
    const [what, value] = action;
    const payload = {
      go: () => EMPTY,
      stop: () => stopPayload(value, inputDelay, this.settings.stop_source),
      distance: () => encodeFloat32(value),
      preference: () => encodeString(value),
      answer: () => encodeString(JSON.stringify(value)), // {administration, item, answer}, as the runner reads it
    }[what]();
    if (this.connection.publish(this.settings.topics[what][0], payload)) this.sent.push([what, value]);
  }
}
