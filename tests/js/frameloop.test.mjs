// The page's frame (sim/study/views/vr/web/frameloop.js) with stand-ins for the scene, the robot, the panel, the
// controllers and the topics: what one frame does in the session and outside it. Run by node's test runner.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { FrameLoop } from '../../sim/study/views/vr/web/frameloop.js';
import { Rest } from '../../sim/study/views/vr/web/rest.js';
import { Participant } from '../../sim/study/views/vr/web/study.js';

const PROTOCOL = JSON.parse(readFileSync(new URL('../../sim/study/run/protocol.json', import.meta.url)));

// A frame loop whose parts write what they are asked into `calls`; the controllers read `input` each frame, the
// tracking `bodies` (the bodies tracked, in the world frame); the topics' clock offset is `clock.offset`, and they
// track the trials of the conditions `tracked`; `rest`: the rest at the session's start (rest.js), or none.
function loopWith(input, connected = true, bodies = [], clock = { offset: null }, tracked = ['vr'], rest = null) {
  const calls = [];
  const participant = new Participant(PROTOCOL);
  const parts = {
    view: { render: () => calls.push('render') },
    robot: { update: () => calls.push('robot') },
    panel: { show: (title, lines, phase) => calls.push(['panel', title, lines, phase]) },
    controllers: {
      read: () => {
        calls.push('controllers');
        return input;
      },
    },
    tracking: {
      read: () => {
        calls.push('tracking');
        return bodies;
      },
    },
    participant,
    topics: {
      connected,
      state: 'connecting to wss://here/ros',
      send: (action) => action && calls.push(action),
      sendPoses: (stamp, sent, condition) =>
        sent.forEach(([body, pose]) => calls.push(['pose', body, stamp, pose, condition])),
      tracks: (condition) => tracked.includes(condition),
      measured: (seconds, jitters) => calls.push(['measured', seconds, jitters]),
      get clockOffset() {
        return clock.offset;
      },
    },
  };
  const restSays = { title: 'Hold still', lines: ['{left} s'] };
  return { loop: new FrameLoop({ ...parts, rest, restSays }), calls, participant };
}

function status(phase, extra = {}) {
  return { index: 1, total: 3, test: 1, condition: 'vr', phase, motion_start: null, group_paths: [], ...extra };
}

const kinds = (calls) => calls.map((call) => (Array.isArray(call) ? call[0] : call));

test('a frame of the session poses the robot, answers from the controllers, shows the panel and draws', () => {
  const { loop, calls, participant } = loopWith({ distance: 0.12, presses: [{ confirm: true, choose: 0 }] });
  participant.onStatus(status('distance'));
  loop.step(0, {});
  assert.deepEqual(
    calls.map((call) => (Array.isArray(call) ? call[0] : call)),
    ['robot', 'controllers', 'distance', 'panel', 'render'],
  );
  assert.deepEqual(calls[2], ['distance', 0.12]);
  assert.equal(loop.frames, 1);
});

test('a thumbstick push is taken before a confirm of the same frame', () => {
  const input = { distance: null, presses: [{ confirm: true, choose: 1 }] };
  const { loop, calls, participant } = loopWith(input);
  participant.onStatus(status('preference', { group_paths: ['straight', 'vertical'] }));
  loop.step(0, {});
  assert.deepEqual(calls[2], ['preference', 'vertical']);
});

test('outside the session no controller is read and no frame counted; the panel says the connection', () => {
  const { loop, calls } = loopWith({ distance: null, presses: [] }, false);
  loop.step(0, undefined);
  assert.deepEqual(
    calls.map((call) => (Array.isArray(call) ? call[0] : call)),
    ['robot', 'panel', 'render'],
  );
  const [, title, lines, phase] = calls[1];
  assert.equal(phase, 'waiting');
  assert.ok(title.length > 0);
  assert.equal(lines.at(-1), '(connecting to wss://here/ros)');
  assert.equal(loop.frames, 0);
});

test("a questionnaire's answer: pushes walk the scale frame by frame, then a confirm sends the point shown", () => {
  const input = { distance: null, presses: [{ confirm: false, choose: 1 }] };
  const { loop, calls, participant } = loopWith(input);
  const item = { administration: 'ssq_after_vr', item: 'fatigue', scale_low: 0, scale_high: 3 };
  participant.onStatus(status('questionnaire', { ...item, scale_labels: ['none', 'slight', 'moderate', 'severe'] }));
  loop.step(0, {});
  loop.step(1, {});
  input.presses = [{ confirm: true, choose: 0 }];
  loop.step(2, {});
  assert.deepEqual(
    calls.filter((call) => call[0] === 'answer'),
    [['answer', { administration: 'ssq_after_vr', item: 'fatigue', answer: 1 }]], // in at 0 from the left, then 1
  );
});

test("in a trial's frame, each tracked body is sent, stamped with the frame's time on the runner's clock", () => {
  const head = { position: [0.55, -0.65, 0.45], orientation: [Math.SQRT1_2, 0, 0, Math.SQRT1_2] };
  const hand = { position: [0.5, -0.4, 0.2], orientation: [0, 0, 0, 1] };
  const clock = { offset: null };
  const { loop, calls, participant } = loopWith(
    { distance: null, presses: [] },
    true,
    [
      ['head', head],
      ['left_hand', hand],
    ],
    clock,
  );
  loop.timeOrigin = 1_764_000_000_000;
  participant.onStatus(status('moving'));
  loop.step(16, {}); // no ROS time yet: nothing to stamp the poses with, so none is read or sent
  assert.deepEqual(kinds(calls), ['robot', 'controllers', 'panel', 'render']);
  assert.equal(loop.poseFrames, 0);
  clock.offset = -1_763_999_990; // ROS time is 10 s when the browser's clock says timeOrigin
  calls.length = 0;
  loop.step(32.5, {});
  assert.deepEqual(kinds(calls), ['robot', 'controllers', 'tracking', 'pose', 'pose', 'panel', 'render']);
  const [[, first, stamp, pose, condition], [, second, sameStamp]] = calls.filter((call) => call[0] === 'pose');
  assert.deepEqual([first, second, pose], ['head', 'left_hand', head]);
  assert.equal(condition, 'vr'); // the trial's, for the page's announcement as its pose source
  assert.ok(Math.abs(stamp - 10.0325) < 1e-6, stamp);
  assert.equal(sameStamp, stamp); // one frame, one time for every body
  assert.equal(loop.poseFrames, 1);
});

test('no pose outside a trial, outside the session, or with the poses switched off', () => {
  const bodies = [['head', { position: [0, 0, 0], orientation: [0, 0, 0, 1] }]];
  const { loop, calls, participant } = loopWith({ distance: null, presses: [] }, true, bodies, { offset: 0 });
  participant.onStatus(status('questionnaire', { test: 0, scale_low: 0, scale_high: 3, scale_labels: [] }));
  loop.step(16, {});
  participant.onStatus(status('done', { index: 0, test: 0 }));
  loop.step(32, {});
  participant.onStatus(status('ready'));
  loop.step(48, undefined); // not in the session
  loop.sendPoses = false; // the frame-time bench's switch
  loop.step(64, {});
  assert.deepEqual(
    calls.filter((call) => call === 'tracking' || call[0] === 'pose'),
    [],
  );
  assert.equal(loop.poseFrames, 0);
  loop.sendPoses = true;
  loop.step(80, {});
  assert.deepEqual(kinds(calls.filter((call) => call === 'tracking' || call[0] === 'pose')), ['tracking', 'pose']);
  assert.equal(loop.poseFrames, 1);
});

test("only a trial of a condition the page tracks sends poses: another tracker may track the other's", () => {
  const bodies = [['head', { position: [0, 0, 0], orientation: [0, 0, 0, 1] }]];
  const { loop, calls, participant } = loopWith({ distance: null, presses: [] }, true, bodies, { offset: 0 });
  participant.onStatus(status('moving', { condition: 'reality' }));
  loop.step(16, {});
  assert.deepEqual(
    calls.filter((call) => call === 'tracking' || call[0] === 'pose'),
    [],
  );
  assert.equal(loop.poseFrames, 0);
  participant.onStatus(status('moving', { index: 2 }));
  loop.step(32, {});
  assert.deepEqual(kinds(calls.filter((call) => call === 'tracking' || call[0] === 'pose')), ['tracking', 'pose']);
});

test("the session's first frames are the rest: the panel asks to hold still, no answer is taken, then the jitter", () => {
  const still = { position: [0.55, -0.65, 0.45], orientation: [0, 0, 0, 1] };
  const input = { distance: 0.1, presses: [{ confirm: true, choose: 0 }] };
  const rest = new Rest(1, ['head', 'left_hand', 'right_hand']);
  const { loop, calls, participant } = loopWith(input, true, [['head', still]], { offset: null }, ['vr'], rest);
  participant.onStatus(status('distance'));
  loop.step(100, undefined); // outside the session: no rest yet
  loop.step(200, {});
  loop.step(700, {});
  // the controllers are read (a press then is not kept for later), but nothing is answered; the panel says the rest
  assert.deepEqual(kinds(calls), [
    'robot',
    'panel',
    'render',
    'robot',
    'tracking',
    'controllers',
    'panel',
    'render',
    'robot',
    'tracking',
    'controllers',
    'panel',
    'render',
  ]);
  assert.deepEqual(calls[6], ['panel', 'Hold still', ['1 s'], 'rest']);
  calls.length = 0;
  loop.step(1200, {}); // a second on: over, the jitter handed on, and this frame answers again
  assert.deepEqual(kinds(calls), ['robot', 'tracking', 'measured', 'controllers', 'distance', 'panel', 'render']);
  assert.deepEqual(calls[2], ['measured', 1, { head: 0, left_hand: null, right_hand: null }]);
  calls.length = 0;
  loop.step(1300, {}); // the distance was sent: a confirm again sends nothing
  assert.deepEqual(kinds(calls), ['robot', 'controllers', 'panel', 'render']);
});
