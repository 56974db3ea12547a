// The page's frame (sim/study/views/vr/web/frameloop.js) with stand-ins for the scene, the robot, the panel, the
// controllers and the topics: what one frame does in the session and outside it. Run by node's test runner.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { FrameLoop } from '../../sim/study/views/vr/web/frameloop.js';
import { Participant } from '../../sim/study/views/vr/web/study.js';

const PROTOCOL = JSON.parse(readFileSync(new URL('../../sim/study/run/protocol.json', import.meta.url)));

// A frame loop whose parts write what they are asked into `calls`; the controllers read `input` each frame.
function loopWith(input, connected = true) {
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
    participant,
    topics: { connected, state: 'connecting to wss://here/ros', send: (action) => action && calls.push(action) },
  };
  return { loop: new FrameLoop(parts), calls, participant };
}

function status(phase, extra = {}) {
  return { index: 1, total: 3, phase, motion_start: null, group_paths: [], ...extra };
}

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
    [['answer', { administration: 'ssq_after_vr', item: 'fatigue', answer: 3 }]],
  );
});
