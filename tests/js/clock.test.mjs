// The page's estimate of ROS time from the endpoint's ping answers (sim/study/views/vr/web/clock.js).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ClockOffset } from '../../sim/study/views/vr/web/clock.js';

test("the offset is the quickest round trip's, taken at its middle", () => {
  const clock = new ClockOffset();
  assert.equal(clock.offset, null);
  clock.add(10_000, 10_100, 110.2); // ROS time 110.2 at browser 10.05 s: 100.15 s ahead, within 0.05 s
  clock.add(12_000, 12_010, 112.155); // quicker: 100.15 s ahead, within 0.005 s
  clock.add(14_000, 14_300, 114.0); // slow and off by 0.15 s: not chosen
  assert.ok(Math.abs(clock.offset - 100.15) < 1e-9);
});

test('a jump of ROS time (a /clock that restarts) drops the samples before it', () => {
  const clock = new ClockOffset();
  clock.add(1_000, 1_002, 50.001); // 49 s ahead
  clock.add(3_000, 3_050, 0.525); // /clock restarted at 0 at browser 2.5 s: slower round trip, yet it wins
  assert.ok(Math.abs(clock.offset - -2.5) < 1e-9);
  assert.equal(clock.samples.length, 1);
});

test('an answer of ROS time 0 (no /clock yet) is no sample, even the quickest just before the clock starts', () => {
  const clock = new ClockOffset();
  clock.add(1_000, 1_002, 0.0); // the endpoint's ROS time before any /clock: 0
  assert.equal(clock.offset, null);
  // /clock starts at browser 1.3 s, within the jump threshold of what the 0 would have stood for (-1.001 s ahead):
  // kept, the quicker 0 would be chosen, 0.3 s off
  clock.add(3_000, 3_050, 1.725);
  assert.ok(Math.abs(clock.offset - -1.3) < 1e-9);
  assert.equal(clock.samples.length, 1);
});

test('only the last few samples count', () => {
  const clock = new ClockOffset();
  clock.add(0, 1, 5.0005); // the quickest (5.0 ahead), then eight slower ones (5.01 ahead)
  for (let k = 1; k <= 8; k += 1) clock.add(k * 1000, k * 1000 + 20, k + 5.02);
  assert.equal(clock.samples.length, 8);
  assert.ok(Math.abs(clock.offset - 5.01) < 1e-9); // the quickest is gone
});

test('ROS time as the page reads it never runs backwards when a new estimate is lower', () => {
  const clock = new ClockOffset();
  clock.add(0, 300, 10.15); // a slow round trip, as a page busy drawing measures it: 10 s ahead
  assert.ok(Math.abs(clock.offsetAt(1_000) - 10.0) < 1e-9);
  clock.add(2_000, 2_020, 11.845); // quicker and 0.165 s lower: the estimate steps back
  assert.ok(Math.abs(clock.offset - 9.835) < 1e-9);
  // frames 170 ms apart, read by the applied offset: it moves 5 ms a second towards the estimate, never past it
  let last = -Infinity;
  for (let now = 2_100; now <= 6_000; now += 170) {
    const rosNow = now / 1000 + clock.offsetAt(now);
    assert.ok(rosNow > last, `ROS time read at ${now} ms went back`);
    last = rosNow;
  }
  assert.ok(Math.abs(clock.offsetAt(40_000) - 9.835) < 1e-9); // reached, and kept
});

test('a jump is read at once, not slewed', () => {
  const clock = new ClockOffset();
  clock.add(1_000, 1_002, 50.001);
  assert.ok(Math.abs(clock.offsetAt(1_500) - 49) < 1e-9);
  clock.add(3_000, 3_050, 0.525); // /clock restarted
  assert.ok(Math.abs(clock.offsetAt(3_100) - -2.5) < 1e-9);
});

test('a report says the offset a read would give without reading it: the stamps are as without it', () => {
  const clock = new ClockOffset();
  assert.equal(clock.report(0), null);
  clock.add(0, 300, 10.15); // 10 s ahead, by a 300 ms round trip
  assert.ok(Math.abs(clock.offsetAt(1_000) - 10.0) < 1e-9);
  clock.add(2_000, 2_020, 11.845); // quicker, 0.165 s lower: the estimate steps back, the applied slews
  const report = clock.report(3_000);
  assert.ok(Math.abs(report.offset - 9.835) < 1e-9 && Math.abs(report.round_trip - 0.02) < 1e-12, report);
  assert.ok(Math.abs(report.applied - (10.0 - 0.1)) < 1e-9, report); // 5 % of the 2 s since the read
  assert.equal(report.samples, 2);
  assert.deepEqual(clock.applied, [1_000, 10.0]); // not read: a read later slews from the last read
  assert.ok(Math.abs(clock.offsetAt(5_000) - 9.835) < 1e-9); // 4 s of slew covers the 0.165 s
});
