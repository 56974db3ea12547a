// How far ROS time is ahead of this browser's clock, from the endpoint's ping answers: pure logic, without a socket,
// so node tests it. Each answer gives one sample: ROS time at the middle of its round trip, minus the browser's clock
// then. The quickest recent round trip gives the best sample. A sample far from the estimate means ROS time jumped
// (a /clock that restarted after the page connected): the samples before it are dropped. An answer of 0 says that
// ROS time has not started (an endpoint under /use_sim_time before the first /clock, or a runner's /clock 0 before
// its first step) and is no sample at all: kept, it would stand for a clock that started within the jump threshold
// after it, and be off by that much until it aged out.

const SAMPLES_KEPT = 8;
const JUMP_S = 0.5; // beyond the round trips' own uncertainty
// The offset the page applies moves towards the estimate by at most this share of the time passed (5 ms a second),
// so ROS time as the page reads it never runs backwards: a new best sample may differ from the last by half a round
// trip, and a page busy drawing (software rendering: 150 ms frames) measures round trips of hundreds of ms. Stepped
// back at once, a frame's pose was stamped before the one drawn 170 ms earlier. A jump (a restarted clock) is taken
// at once.
const SLEW = 0.05;

export class ClockOffset {
  constructor() {
    this.samples = []; // [round trip ms, offset s], oldest first
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
    this.samples.push([roundTripMs, offset]);
    this.samples = this.samples.slice(-SAMPLES_KEPT);
    return true;
  }

  best() {
    if (this.samples.length === 0) return null;
    return this.samples.reduce((best, sample) => (sample[0] < best[0] ? sample : best));
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

  // The offset to read ROS time by at nowMs (browser clock, ms; not before the last read): the estimate, reached
  // at no more than SLEW of the time passed since the last read, so that readings never run backwards.
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
    const most = (SLEW * Math.max(0, nowMs - readAt)) / 1000;
    return [Math.max(readAt, nowMs), applied + Math.min(most, Math.max(-most, target - applied))];
  }
}
