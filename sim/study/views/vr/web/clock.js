// How far ROS time is ahead of this browser's clock, from the endpoint's ping answers, and when to ping: pure logic,
// without a socket, so node tests it. Each answer gives one sample: ROS time at the middle of its round trip, minus
// the browser's clock then. The quickest round trip of the last SAMPLES_SPAN_MS gives the best sample. A sample far
// from the estimate means ROS time jumped (a /clock that restarted after the page connected): the samples before it
// are dropped. An answer of 0 says that ROS time has not started (an endpoint under /use_sim_time before the first
// /clock, or a runner's /clock 0 before its first step) and is no sample at all: kept, it would stand for a clock
// that started within the jump threshold after it, and be off by that much until it aged out.

// The samples kept: those of the last 16 s (8 at the settled pace; at most SAMPLES_MOST at the quick one), so that a
// quick round trip counts as long at either pace. Two clocks drift apart by well under a millisecond in 16 s.
const SAMPLES_SPAN_MS = 16_000;
const SAMPLES_MOST = 64;
const JUMP_S = 0.5; // beyond the round trips' own uncertainty
// When to ping the endpoint (pingDue). Every PING_EVERY_MS once the estimate is settled: SAMPLES_SETTLED samples, the
// best of them a round trip of at most SETTLED_ROUND_TRIP_MS (a stamp's error within half the runner's limit, 20 ms).
// Until then every PING_QUICK_MS: after connecting (ROS time not started yet counts), after a jump dropped the
// samples, and while the round trips are slow. A page that just connected had one sample at the runner's first go,
// 2 s after its /clock started, and a page building its scene or drawing in software reads a ping's answer only once
// its main thread is free: that one sample's round trip held a frame's work (47 and 60 ms, beside two CPU burners;
// its pings' median 53-60 ms, against 11-18 ms timed in a worker of the page's own). Quick pings give it eight
// chances in 2 s, and more while none is quick, to see an answer between two frames: the best at the first go was
// then 1-38 ms, median 12 ms (27 runs). A worker timing its pings off the main thread would need a second
// WebSocket, a second client of the endpoint's, for every page. Quick pings were not always enough (once, beside
// other work, none quicker than 60 ms by the first go), so the runner holds the arm at the start up to 5 s more
// for a clock still beyond its limit (sim/study/run/clocks.py): 20 more quick pings.
// A flood cannot come of it: one ping at a time (the next once it is answered, or given up on after
// PING_GIVE_UP_MS), at most one each PING_QUICK_MS: 4 answers a second from the endpoint at most.
export const PING_EVERY_MS = 2000; // settled: a /clock that starts after the page connected is seen within this
export const PING_QUICK_MS = 250;
export const PING_GIVE_UP_MS = 5000;
const SAMPLES_SETTLED = 8;
const SETTLED_ROUND_TRIP_MS = 20;
// The offset the page applies moves towards the estimate by at most SLEW of the time passed (5 ms a second), so ROS
// time as the page reads it never runs backwards, and a new best sample (it may differ from the last by half a round
// trip) changes the time between two stamps by 5 % at most. Stepped back at once, a frame's pose was stamped before
// the one drawn 170 ms earlier (software rendering, round trips of hundreds of ms). Yet a page whose estimate improved
// by 20 ms just before the runner's go (a better sample among its first) would stamp 20 ms off for 4 s, and be
// refused: so while the applied offset is more than LAG_MOST_S off the estimate, it moves up to SLEW_MOST of the time
// passed (ROS time as read runs at half speed at the least, never backwards), then at SLEW the rest; the page
// announces its clock again once within LAG_MOST_S (connection.js). A jump (a restarted clock) is taken at once.
const SLEW = 0.05;
const SLEW_MOST = 0.5;
const LAG_MOST_S = 0.002;

export class ClockOffset {
  constructor() {
    this.samples = []; // [round trip ms, offset s, received at (browser clock, ms)], oldest first
    this.applied = null; // [browser ms, offset s]: the offset last read (offsetAt), null until read or after a jump
  }

  // A ping sent at sentAtMs (browser clock, ms) was answered at receivedAtMs with ROS time rosTime (s); whether it
  // gave a sample.
  add(sentAtMs, receivedAtMs, rosTime) {
    if (!(rosTime > 0)) return false;
    const roundTripMs = receivedAtMs - sentAtMs;
    const offset = rosTime - (sentAtMs + roundTripMs / 2) / 1000;
    const best = this.best();
    if (best !== null && Math.abs(offset - best[1]) > JUMP_S + (roundTripMs + best[0]) / 2000) {
      this.samples = [];
      this.applied = null;
    }
    this.samples.push([roundTripMs, offset, receivedAtMs]);
    this.samples = this.samples.filter((sample) => receivedAtMs - sample[2] < SAMPLES_SPAN_MS).slice(-SAMPLES_MOST);
    return true;
  }

  // The best sample: [round trip ms, offset s], or null before any. The quickest of those not stale: a sample says
  // the offset is within half its round trip of its own, and each says at least as much of the lowest it can be. The
  // endpoint answers with the latest /clock it has, which lags when the runner or the endpoint is short of CPU (117 ms
  // once, beside two CPU burners, answered in 21 ms): a stale answer gives an offset too low, never too high, so one
  // whose highest is below another's lowest is stale, and is not chosen, however quick.
  best() {
    if (this.samples.length === 0) return null;
    const lowest = Math.max(...this.samples.map(([roundTripMs, offset]) => offset - roundTripMs / 2000));
    const fresh = this.samples.filter(([roundTripMs, offset]) => offset + roundTripMs / 2000 >= lowest);
    const [roundTripMs, offset] = fresh.reduce((best, sample) => (sample[0] < best[0] ? sample : best));
    return [roundTripMs, offset];
  }

  // Whether the estimate has enough samples, the best of them quick enough: the page pings at the settled pace.
  get settled() {
    return this.samples.length >= SAMPLES_SETTLED && this.best()[0] <= SETTLED_ROUND_TRIP_MS;
  }

  // ROS time minus the browser's clock (s), or null before any answer: the estimate.
  get offset() {
    const best = this.best();
    return best === null ? null : best[1];
  }

  // What the page says of its clock at nowMs (browser clock, ms; not before the last read), or null before any
  // answer: the estimate (s) and its round trip (s), the offset it stamps with now (s) and the samples it is of. The
  // runner judges the page's stamps by it (sim/study/run/clocks.py): off by at most half the round trip plus the
  // applied offset's distance from the estimate.
  // Reporting reads nothing: the offset a read would give is not kept, so the stamps are as without the report (a
  // page that reads ROS time only at a press, the stop button's, takes the estimate then).
  report(nowMs) {
    const best = this.best();
    if (best === null) return null;
    const applied = this._slewed(nowMs)[1];
    return { offset: best[1], round_trip: best[0] / 1000, applied, samples: this.samples.length };
  }

  // Whether the offset a read at nowMs would give is more than LAG_MOST_S off the estimate (being taken up quickly;
  // a microsecond for rounding: the quick catch-up stops at LAG_MOST_S).
  lagging(nowMs) {
    return this.offset !== null && Math.abs(this._slewed(nowMs)[1] - this.offset) > LAG_MOST_S + 1e-6;
  }

  // The offset to read ROS time by at nowMs (browser clock, ms; not before the last read): the estimate, reached
  // at no more than SLEW of the time passed since the last read (SLEW_MOST while more than LAG_MOST_S off it), so
  // that readings never run backwards.
  offsetAt(nowMs) {
    if (this.offset === null) return null;
    this.applied = this._slewed(nowMs);
    return this.applied[1];
  }

  // [read at, offset] for a read at nowMs, the estimate not null.
  _slewed(nowMs) {
    const target = this.offset;
    if (this.applied === null) return [nowMs, target];
    const [readAt, applied] = this.applied;
    const passed = Math.max(0, nowMs - readAt) / 1000;
    const lag = Math.abs(target - applied);
    const most = Math.max(SLEW * passed, Math.min(SLEW_MOST * passed, lag - LAG_MOST_S));
    return [Math.max(readAt, nowMs), applied + Math.sign(target - applied) * Math.min(most, lag)];
  }
}

// Whether to send a ping at nowMs (ms, the browser's clock): lastSentMs when the last was sent (null: none since
// connecting), unansweredSinceMs when the oldest ping still unanswered was (null: none), settled the estimate's.
export function pingDue(nowMs, lastSentMs, unansweredSinceMs, settled) {
  if (unansweredSinceMs !== null && nowMs - unansweredSinceMs < PING_GIVE_UP_MS) return false;
  if (lastSentMs === null) return true;
  return nowMs - lastSentMs >= (settled ? PING_EVERY_MS : PING_QUICK_MS);
}
