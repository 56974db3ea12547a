// The page's estimate of ROS time from the endpoint's ping answers (sim/study/views/vr/web/clock.js).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ClockOffset, pingDue } from '../../sim/study/views/vr/web/clock.js';
import { RosConnection, browserClockMs } from '../../sim/study/views/vr/web/connection.js';
import { commandFields, decodeString, framesIn } from '../../sim/study/views/vr/web/rostcp.js';

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

test('only the samples of the last 16 s count, at most 64', () => {
  const clock = new ClockOffset();
  clock.add(0, 1, 5.0005); // the quickest (5.0 ahead), then eight slower ones (5.005 ahead) at the settled pace
  for (let k = 1; k <= 8; k += 1) clock.add(k * 2000, k * 2000 + 20, (k * 2000 + 10) / 1000 + 5.005);
  assert.equal(clock.samples.length, 8);
  assert.ok(Math.abs(clock.offset - 5.005) < 1e-9); // the quickest is gone: received 16.019 s before the last
  const quick = new ClockOffset();
  for (let k = 0; k < 100; k += 1) quick.add(k * 100, k * 100 + 20, (k * 100 + 10) / 1000 + 5.0); // 10 a second
  assert.equal(quick.samples.length, 64);
});

test('a stale answer (a /clock that lagged) is not chosen, however quick', () => {
  const clock = new ClockOffset();
  clock.add(1_000, 1_022, 101.011); // 22 ms: 100.0 s ahead, within 11 ms
  clock.add(1_250, 1_271, 101.1435); // 21 ms, but ROS time 117 ms behind: 99.883 ahead, at most 99.8935
  assert.ok(Math.abs(clock.offset - 100.0) < 1e-9);
  clock.add(1_500, 1_504, 101.5025); // 4 ms, fresh: 100.0005 ahead, within 2 ms of the first
  assert.ok(Math.abs(clock.offset - 100.0005) < 1e-9);
  assert.equal(clock.samples.length, 3); // kept, and never chosen while the fresh ones stand
});

test('ROS time as the page reads it never runs backwards when a new estimate is lower', () => {
  const clock = new ClockOffset();
  clock.add(0, 300, 10.15); // a slow round trip, as a page busy drawing measures it: 10 s ahead, within 0.15 s
  assert.ok(Math.abs(clock.offsetAt(1_000) - 10.0) < 1e-9);
  clock.add(2_000, 2_020, 11.86); // quicker and 0.15 s lower: the estimate steps back
  assert.ok(Math.abs(clock.offset - 9.85) < 1e-9);
  // frames 170 ms apart, read by the applied offset: it moves towards the estimate, never past it, ROS time as
  // read at least half as fast as the browser's clock while more than 2 ms off it, then at 95 % of it
  let [lastMs, last] = [1_000, 1_000 / 1000 + 10.0];
  for (let now = 2_100; now <= 6_000; now += 170) {
    const rosNow = now / 1000 + clock.offsetAt(now);
    const lag = clock.offsetAt(now) - clock.offset;
    assert.ok(lag >= -1e-12, `the applied offset passed the estimate at ${now} ms`);
    assert.ok(rosNow - last >= (lag > 0.002 ? 0.5 : 0.95) * ((now - lastMs) / 1000) - 1e-9, `slow at ${now} ms`);
    if (now === 2_440) assert.ok(lag < 0.002 + 1e-9, `${lag} s off 0.34 s after: taken up at only 5 ms a second`);
    [lastMs, last] = [now, rosNow];
  }
  assert.ok(Math.abs(clock.offsetAt(40_000) - 9.85) < 1e-9); // reached, and kept
});

test('a lag of 2 ms or less is taken up at 5 ms a second', () => {
  const clock = new ClockOffset();
  clock.add(0, 10, 10.005); // 10 s ahead, within 5 ms
  assert.ok(Math.abs(clock.offsetAt(990) - 10.0) < 1e-9);
  clock.add(1_000, 1_002, 11.0); // 9.999 ahead: 1 ms lower
  assert.ok(Math.abs(clock.offsetAt(1_006) - (10.0 - 0.0008)) < 1e-9); // 5 % of the 16 ms since the last read
  assert.ok(Math.abs(clock.offsetAt(1_100) - 9.999) < 1e-9);
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
  clock.add(2_000, 2_020, 11.86); // quicker, 0.15 s lower: the estimate steps back, the applied slews
  const report = clock.report(3_000);
  assert.ok(Math.abs(report.offset - 9.85) < 1e-9 && Math.abs(report.round_trip - 0.02) < 1e-12, report);
  assert.ok(Math.abs(report.applied - (9.85 + 0.002)) < 1e-9, report); // half the 2 s since the read, to 2 ms off
  assert.equal(report.samples, 2);
  assert.deepEqual(clock.applied, [1_000, 10.0]); // not read: a read later slews from the last read
  assert.ok(Math.abs(clock.offsetAt(5_000) - 9.85) < 1e-9); // 4 s: 5 % of them covers the last 2 ms
});

test('the page pings quickly until its estimate is settled: eight samples, the best within 20 ms', () => {
  const clock = new ClockOffset();
  assert.equal(clock.settled, false);
  for (let k = 0; k < 7; k += 1) clock.add(k * 250, k * 250 + 10, (k * 250 + 5) / 1000 + 3.0);
  assert.equal(clock.settled, false); // seven
  clock.add(1_750, 1_760, 4.755);
  assert.equal(clock.settled, true);
  const slow = new ClockOffset();
  for (let k = 0; k < 20; k += 1) slow.add(k * 250, k * 250 + 30, (k * 250 + 15) / 1000 + 3.0);
  assert.equal(slow.settled, false); // twenty, none within 20 ms: it goes on pinging quickly
  slow.add(5_000, 5_020, 8.01);
  assert.equal(slow.settled, true);
  slow.add(5_250, 5_250, 0.5); // a jump (a restarted clock): its samples are dropped, and it pings quickly again
  assert.equal(slow.settled, false);
});

test('a ping is due at the pace its estimate asks, one at a time', () => {
  assert.equal(pingDue(0, null, null, false), true); // the first on a connection
  assert.equal(pingDue(1_000, 800, null, false), false); // quick: 250 ms apart
  assert.equal(pingDue(1_050, 800, null, false), true);
  assert.equal(pingDue(2_000, 800, null, true), false); // settled: 2 s apart
  assert.equal(pingDue(2_800, 800, null, true), true);
  assert.equal(pingDue(5_000, 800, 800, false), false); // one unanswered: the next waits for its answer
  assert.equal(pingDue(5_800, 800, 800, false), true); // or gives it up after 5 s
});

test('the connection sends no flood of pings: one at a time, one each 250 ms at most, none after a loss', () => {
  const connection = new RosConnection('ws://x');
  const sent = [];
  connection._send = (bytes) => sent.push(commandFields(framesIn(bytes)[0][1]).request_time);
  let now = 1_000_000;
  connection.clockMs = () => now;
  connection._ping(); // as the socket opens
  for (let tick = 0; tick < 200; tick += 1) {
    now += 10; // 2 s of ticks far quicker than the page's, no answer: the one ping stays alone
    connection._pingIfDue();
  }
  assert.equal(sent.length, 1);
  const answer = (requestTime, rosTime) => {
    connection._system('__ping_response', { request_time: requestTime, ros_time: rosTime });
  };
  answer(sent[0], 0); // ROS time not started: no sample, quick pings on
  for (let tick = 0; tick < 200; tick += 1) {
    now += 10;
    connection._pingIfDue();
    if (connection.pings.size) answer(sent.at(-1), 0); // answered at once: 250 ms apart still
  }
  assert.equal(sent.length, 1 + 8); // 2 s at 250 ms
  now += 10;
  connection._pingIfDue();
  now += 6_000; // unanswered for 5 s and more: given up, the next sent
  connection._pingIfDue();
  assert.equal(sent.length, 1 + 8 + 2);
  assert.equal(connection.pings.size, 1);
});

test('a lag announced is announced again once a read has taken it up', () => {
  const connection = new RosConnection('ws://x');
  connection.announceClock('/study/page_clock', 'std_msgs/String', 'vr_trigger');
  const said = [];
  connection._send = (bytes) => said.push(JSON.parse(decodeString(framesIn(bytes)[0][1])));
  connection.connected = true;
  let now = 1_000_000;
  connection.clockMs = () => now;
  const answer = (roundTripMs, rosTime) => {
    connection.pings.set(`#${now}`, now - roundTripMs);
    connection._system('__ping_response', { request_time: `#${now}`, ros_time: rosTime });
  };
  answer(30, 2_000.0); // 30 ms: ROS time 1000.015 s ahead
  connection.clockOffset; // a frame's read: the page stamps with it
  now += 1;
  answer(4, 2_000.002); // 4 ms: 1000.003 s ahead, 12 ms lower, read 1 ms after a frame: nearly all of it a lag
  assert.equal(said.length, 2);
  assert.ok(Math.abs(said[1].applied - said[1].offset - 0.0115) < 1e-9, said[1]);
  now += 10;
  connection.clockOffset; // 5.5 ms taken up: still lagging, nothing said
  assert.equal(said.length, 2);
  now += 40;
  connection.clockOffset; // within 2 ms: said again
  connection.clockOffset;
  assert.equal(said.length, 3);
  assert.ok(Math.abs(said[2].applied - said[2].offset) <= 0.002 + 1e-9, said[2]);
});

test("a reading at an instant of the browser's clock is the ROS time then, with the offset it was read by", () => {
  const connection = new RosConnection('ws://x');
  let now = 1_000_000;
  connection.clockMs = () => now;
  assert.equal(connection.rosReading(), null); // no estimate yet
  connection.pings.set('#1', now - 4);
  connection._system('__ping_response', { request_time: '#1', ros_time: 2_000.0 }); // 4 ms: 1000.002 s ahead
  now += 7; // the page's work between a gamepad's reading (its input delay's end) and its stamp
  const atReading = connection.rosReading(now - 7);
  const later = connection.rosReading();
  assert.ok(Math.abs(atReading.offset - (2_000.0 - 999.998)) < 1e-9, atReading);
  assert.ok(Math.abs(later.ros - atReading.ros - 0.007) < 1e-9, [atReading, later]);
  assert.ok(Math.abs(connection.rosNow(now - 7) - atReading.ros) < 1e-9);
  // performance.now()'s instants on that clock: the Gamepad API's and the trigger events' times are on it
  assert.equal(browserClockMs(12.5), performance.timeOrigin + 12.5);
});
