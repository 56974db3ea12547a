// The participant at rest at the headset session's start: for the declared seconds, head and hands held still, each
// tracked body's positions (in the scene's world frame) are kept, and its jitter is their RMS distance from their
// mean, the measure the tracker relay takes of a tracker in reality (jitter() in sim/study/motion/calibration.py).
// The withdrawal's peak speed is sensitive to it, so the page announces it as its pose source's. Pure: no three.js
// and no WebXR, so node runs it for the tests; frameloop.js feeds it the frames.

// The RMS distance (m) of positions ([x, y, z] each) from their mean; null for fewer than two (not measured, never
// 0: a body seen once, or never, says nothing of its steadiness).
export function jitter(positions) {
  if (positions.length < 2) return null;
  const mean = [0, 1, 2].map((k) => positions.reduce((sum, p) => sum + p[k], 0) / positions.length);
  const squares = positions.reduce(
    (sum, p) => sum + (p[0] - mean[0]) ** 2 + (p[1] - mean[1]) ** 2 + (p[2] - mean[2]) ** 2,
    0,
  );
  return Math.sqrt(squares / positions.length);
}

export class Rest {
  // seconds: how long the bodies rest (the page's settings, as declared to `vr --rest`); bodies: the protocol's.
  constructor(seconds, bodies) {
    this.seconds = seconds;
    this.samples = Object.fromEntries(bodies.map((body) => [body, []])); // body -> positions at rest
    this.startMs = null; // the rest's first frame's time (ms, the animation loop's)
    this.done = false;
  }

  // A frame of the session at timeMs, with the bodies tracked in it ([body, {position}], poses.js's world frame):
  // true while the rest goes on, this frame's positions kept; false once it is over (the frame that ends it is not
  // part of it; every later one is neither).
  frame(timeMs, bodies) {
    if (this.done) return false;
    if (this.startMs === null) this.startMs = timeMs;
    if (timeMs - this.startMs >= this.seconds * 1000) {
      this.done = true;
      return false;
    }
    for (const [body, pose] of bodies) if (body in this.samples) this.samples[body].push(pose.position);
    return true;
  }

  // Whole seconds left at timeMs, for the panel (the declared seconds before the first frame).
  secondsLeft(timeMs) {
    if (this.startMs === null) return Math.ceil(this.seconds);
    return Math.max(0, Math.ceil(this.seconds - (timeMs - this.startMs) / 1000));
  }

  // Each body's jitter (m), null where it was not tracked in two frames of the rest.
  jitters() {
    return Object.fromEntries(Object.entries(this.samples).map(([body, positions]) => [body, jitter(positions)]));
  }
}

// What the panel says during the rest: the settings' words ({title, lines}), {seconds} the declared seconds and
// {left} the whole seconds left.
export function restWords(words, seconds, left) {
  const fill = (line) => line.replace('{seconds}', String(seconds)).replace('{left}', String(left));
  return [fill(words.title), words.lines.map(fill)];
}
