// The frame-time instrument of bench/vr_frame_bench.py (window.vrFrameTime): served and loaded only with the page
// server's --frame-time. It takes the page's animation loop over, to time each frame of the session from before the
// robot is posed to after both eyes are drawn, and the interval between frames.
import { page } from './page.js';

const FRAMES_KEPT = 600;

class FrameTimes {
  constructor(renderer) {
    this.renderer = renderer;
    // Set, each frame waits for its rendering to end, by reading one pixel back (Chromium's gl.finish() returns
    // before its GPU process has drawn): the work then includes the rendering.
    this.waitForRendering = false;
    this.work = []; // ms of each frame's work, oldest first
    this.intervals = []; // ms between the session's frames
    this.lastFrameAt = null;
    this.pixel = new Uint8Array(4);
  }

  // `step` (the page's frame), timed.
  timed(step) {
    return (time, frame) => {
      const started = performance.now();
      if (frame && this.lastFrameAt !== null) keep(this.intervals, time - this.lastFrameAt);
      this.lastFrameAt = frame ? time : null;
      step(time, frame);
      if (!frame) return;
      if (this.waitForRendering) {
        const gl = this.renderer.getContext();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, this.pixel);
      }
      keep(this.work, performance.now() - started);
    };
  }
}

function keep(values, value) {
  values.push(value);
  if (values.length > FRAMES_KEPT) values.shift();
}

const times = new FrameTimes(page.view.renderer);
page.view.renderer.setAnimationLoop(times.timed((time, frame) => page.loop.step(time, frame)));
window.vrFrameTime = times;
