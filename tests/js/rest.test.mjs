// The rest at the headset session's start (sim/study/views/vr/web/rest.js): each body's jitter, the RMS distance of its
// positions from their mean (the tracker relay's measure, sim/study/motion/calibration.py's jitter), over the declared
// seconds of frames; a body not tracked in two of them is not measured (null), never 0. Run by node's test runner.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { Rest, jitter, restWords } from '../../sim/study/views/vr/web/rest.js';

const BODIES = ['head', 'left_hand', 'right_hand'];
const at = (position) => ({ position, orientation: [0, 0, 0, 1] });

test('jitter is the RMS distance from the mean, in 3-D; null for fewer than two positions', () => {
  assert.equal(jitter([]), null);
  assert.equal(jitter([[0.1, 0.2, 0.3]]), null);
  assert.equal(
    jitter([
      [0.5, 0.5, 0.5],
      [0.5, 0.5, 0.5],
    ]),
    0,
  );
  // two points 6 apart along (1, 2, 2)/3: each 3 from their mean
  assert.equal(
    jitter([
      [1, 2, 2],
      [-1, -2, -2],
    ]),
    3,
  );
  // the same points, one of them twice: the mean moves, the RMS is sqrt(mean of squared distances) = 6 sqrt(2)/3
  const three = jitter([
    [1, 2, 2],
    [1, 2, 2],
    [-1, -2, -2],
  ]);
  assert.ok(Math.abs(three - (6 * Math.SQRT2) / 3) < 1e-12, three);
  // a ramp of n points a step apart: step sqrt((n^2 - 1) / 12), far from the origin (no cancellation)
  const ramp = Array.from({ length: 5 }, (_, k) => [100 + 0.002 * k, -50, 7]);
  assert.ok(Math.abs(jitter(ramp) - 0.002 * Math.sqrt(24 / 12)) < 1e-9, jitter(ramp));
});

test("the rest keeps each tracked body's positions for its seconds of frames, then gives their jitter", () => {
  const rest = new Rest(3, BODIES);
  assert.equal(rest.secondsLeft(0), 3);
  // the session's first frame starts it; the left hand moves 4 mm, back and forth; the right hand is seen once
  assert.equal(
    rest.frame(1000, [
      ['head', at([0.55, -0.65, 0.45])],
      ['left_hand', at([0.3, -0.4, 0.1])],
    ]),
    true,
  );
  assert.equal(rest.secondsLeft(1000), 3);
  assert.equal(
    rest.frame(2500, [
      ['head', at([0.55, -0.65, 0.45])],
      ['left_hand', at([0.304, -0.4, 0.1])],
    ]),
    true,
  );
  assert.equal(rest.secondsLeft(2500), 2);
  assert.equal(
    rest.frame(3999, [
      ['head', at([0.55, -0.65, 0.45])],
      ['right_hand', at([0.5, -0.4, 0.1])],
    ]),
    true,
  );
  assert.equal(rest.done, false);
  // the frame at its end is not part of it: a move then counts for nothing
  assert.equal(rest.frame(4000, [['head', at([9, 9, 9])]]), false);
  assert.equal(rest.done, true);
  assert.equal(rest.secondsLeft(4000), 0);
  assert.equal(rest.frame(4100, [['head', at([9, 9, 9])]]), false);
  const jitters = rest.jitters();
  assert.deepEqual(Object.keys(jitters), BODIES);
  assert.ok(jitters.head >= 0 && jitters.head < 1e-12, jitters.head); // still: 0 but for the mean's rounding
  assert.ok(Math.abs(jitters.left_hand - 0.002) < 1e-12, jitters.left_hand);
  assert.equal(jitters.right_hand, null); // tracked in one frame only: not measured
});

test("a body never tracked during the rest is not measured; a body that is not the protocol's is not kept", () => {
  const rest = new Rest(0.5, BODIES);
  rest.frame(0, [
    ['head', at([0, 0, 1])],
    ['tail', at([0, 0, 0])],
  ]);
  rest.frame(100, [
    ['head', at([0, 0, 1])],
    ['tail', at([1, 0, 0])],
  ]);
  rest.frame(600, []);
  assert.deepEqual(rest.jitters(), { head: 0, left_hand: null, right_hand: null });
});

test("the panel's words during the rest", () => {
  const words = { title: 'Hold still', lines: ['for {seconds} s', '{left} s'] };
  assert.deepEqual(restWords(words, 3, 2), ['Hold still', ['for 3 s', '2 s']]);
});
