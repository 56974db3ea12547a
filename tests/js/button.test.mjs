// The stop button's logic (sim/study/views/vr/web/gamepad.js, presses.js) and both pages' measure of a press's input
// delay (presses.js), run by node's test runner with plain objects for the Gamepad API's snapshots.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { GamepadPresses } from '../../sim/study/views/vr/web/gamepad.js';
import { inputDelay, inputDelaySeq, stopPayload } from '../../sim/study/views/vr/web/presses.js';

// A Gamepad API snapshot: `down` lists the pressed buttons' indices.
function pad(index, id, down, timestamp, count = 4) {
  const buttons = Array.from({ length: count }, (_, k) => ({
    pressed: down.includes(k),
    value: down.includes(k) ? 1 : 0,
  }));
  return { index, id, connected: true, timestamp, buttons, axes: [] };
}

test('a press is the edge of any button of any gamepad, once, with its input delay', () => {
  const presses = new GamepadPresses();
  assert.deepEqual(presses.update([pad(0, 'pedal', [], 100), null], 110), []); // first sight: no press
  assert.deepEqual(presses.update([pad(0, 'pedal', [2], 112.5), pad(1, 'gamepad', [], 90)], 120.5), [
    { gamepad: 'pedal', index: 0, control: 2, inputDelay: 0.008 },
  ]);
  assert.deepEqual(presses.update([pad(0, 'pedal', [2], 112.5), pad(1, 'gamepad', [7], 130, 8)], 131), [
    { gamepad: 'gamepad', index: 1, control: 7, inputDelay: 0.001 },
  ]); // held: no second press; another pad's button 7
  assert.deepEqual(presses.update([pad(0, 'pedal', [], 140), pad(1, 'gamepad', [], 140, 8)], 141), []); // releases
  assert.equal(presses.update([pad(0, 'pedal', [0, 3], 150)], 151).length, 2); // two buttons at once: two presses
  assert.deepEqual(presses.connected, [{ index: 0, id: 'pedal' }]); // the gamepad that went is forgotten
});

test('a button held while its gamepad is plugged in, or another pad in its place, is no press', () => {
  const presses = new GamepadPresses();
  assert.deepEqual(presses.update([pad(0, 'pedal', [0], 10)], 11), []);
  assert.deepEqual(presses.update([pad(0, 'other pedal', [0, 1], 20)], 21), []);
  assert.deepEqual(presses.update([null, null], 30), []);
  assert.deepEqual(presses.update([pad(0, 'pedal', [0], 40)], 41), []); // back, held: still none
  assert.equal(presses.update([pad(0, 'pedal', [0, 1], 50)], 51).length, 1);
});

test("the input delay is the reading's time minus the gamepad's last change, when it has a usable one", () => {
  assert.equal(inputDelay(1016.5, 1000), 0.0165);
  assert.equal(inputDelay(1000, 0), null); // a gamepad that keeps no timestamp
  assert.equal(inputDelay(1000, undefined), null);
  assert.equal(inputDelay(1000, 1000.5), null); // after the reading: not on this clock
  const presses = new GamepadPresses();
  presses.update([pad(0, 'pedal', [], 0)], 5);
  assert.equal(presses.update([pad(0, 'pedal', [1], 0)], 25)[0].inputDelay, null);
});

test("a press's Header carries its input delay in microseconds in the seq, 0 when not measured", () => {
  assert.equal(inputDelaySeq(0.0083), 8300);
  assert.equal(inputDelaySeq(0), 1); // measured: never 0
  assert.equal(inputDelaySeq(null), 0);
  assert.equal(inputDelaySeq(-0.001), 0);
  assert.equal(inputDelaySeq(1e9), 2 ** 32 - 1);
  const header = stopPayload(12.5, 0.0165, 'some source');
  const view = new DataView(header.buffer);
  assert.deepEqual([view.getUint32(0, true), view.getUint32(4, true), view.getUint32(8, true)], [16500, 12, 5e8]);
});

test("both pages' input delay: from the first reading that saw the change to the stamp, or none", () => {
  // the VR page: the trigger's event fired at the frame that read it (its timeStamp), stamped 3 ms later
  assert.equal(inputDelay(1003, 1000), 0.003);
  assert.equal(inputDelay(1000, 1000), 0);
  // a time of 0 or none (a browser that keeps none), or after the stamp (another clock): not measured
  for (const readAt of [0, undefined, null, 1004]) assert.equal(inputDelay(1003, readAt), null);
});
