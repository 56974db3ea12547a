// How far ROS time is ahead of this browser's clock, from the endpoint's ping answers: pure logic, without a socket,
// so node tests it. Each answer gives one sample: ROS time at the middle of its round trip, minus the browser's clock
// then. The quickest recent round trip gives the best sample. A sample far from the estimate means ROS time jumped
// (a /clock that restarted after the page connected): the samples before it are dropped. An answer of 0 says that
// ROS time has not started (an endpoint under /use_sim_time before the first /clock, or a runner's /clock 0 before
// its first step) and is no sample at all: kept, it would stand for a clock that started within the jump threshold
// after it, and be off by that much until it aged out.

const SAMPLES_KEPT = 8;
const JUMP_S = 0.5; // beyond the round trips' own uncertainty

export class ClockOffset {
  constructor() {
    this.samples = []; // [round trip ms, offset s], oldest first
  }

  // A ping sent at sentAtMs (browser clock, ms) was answered at receivedAtMs with ROS time rosTime (s).
  add(sentAtMs, receivedAtMs, rosTime) {
    if (!(rosTime > 0)) return;
    const roundTripMs = receivedAtMs - sentAtMs;
    const offset = rosTime - (sentAtMs + roundTripMs / 2) / 1000;
    const best = this.best();
    if (best !== null && Math.abs(offset - best[1]) > JUMP_S + (roundTripMs + best[0]) / 2000) this.samples = [];
    this.samples.push([roundTripMs, offset]);
    this.samples = this.samples.slice(-SAMPLES_KEPT);
  }

  best() {
    if (this.samples.length === 0) return null;
    return this.samples.reduce((best, sample) => (sample[0] < best[0] ? sample : best));
  }

  // ROS time minus the browser's clock (s), or null before any answer.
  get offset() {
    const best = this.best();
    return best === null ? null : best[1];
  }
}
