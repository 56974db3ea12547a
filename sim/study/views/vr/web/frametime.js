// The frame-time instrument of bench/vr_frame_bench.py (window.vrFrameTime): served and loaded only with the page
// server's --frame-time. It takes the page's animation loop over, to time each frame of the session from before the
// robot is posed to after both eyes are drawn, and the interval between frames; and it switches the frame loop's
// poses (the tracked body, sent during a trial) off and on, so that the bench measures what they cost.
import { page } from './page.js';

const FRAMES_KEPT = 20000; // between two takes: minutes of frames at a headset's rate

class FrameTimes {
  constructor(renderer, loop, topics) {
    this.renderer = renderer;
    this.loop = loop;
    this.topics = topics;
    // Set, each frame waits for its rendering to end, by reading one pixel back (Chromium's gl.finish() returns
    // before its GPU process has drawn): the work then includes the rendering.
    this.waitForRendering = false;
    this.lastFrameAt = null;
    this.pixel = new Uint8Array(4);
    this.clear();
    // the poses' own part of a frame (reading the bodies, encoding and sending them), timed where it runs: a
    // difference of two frame times, each hundreds of times longer, could not show it
    const sendBody = loop.sendBody.bind(loop);
    loop.sendBody = (time, frame) => {
      const started = performance.now();
      sendBody(time, frame);
      this.poseWorkNow += performance.now() - started;
    };
  }

  clear() {
    this.work = []; // ms of each frame's work, oldest first
    this.intervals = []; // ms between the session's frames
    this.posesOn = []; // each frame: whether the frame loop sent poses
    this.poses = []; // each frame: the poses it sent
    this.poseWork = []; // each frame: ms of its poses' part (0 with them off)
    this.poseWorkNow = 0;
  }

  // The frames since the last take, as plain data; then poses off or on (`on`) from the next frame. One call, so
  // that no frame falls between the take and the switch.
  take(on) {
    const { work, intervals, posesOn, poses, poseWork } = this;
    const taken = { work, intervals, posesOn, poses, poseWork };
    this.clear();
    this.loop.sendPoses = on;
    return taken;
  }

  // `step` (the page's frame), timed.
  timed(step) {
    return (time, frame) => {
      const sentBefore = frame ? this.posesSent() : 0; // outside the frame's time: the bench's, not the page's
      this.poseWorkNow = 0;
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
      keep(this.posesOn, this.loop.sendPoses);
      keep(this.poses, this.posesSent() - sentBefore);
      keep(this.poseWork, this.poseWorkNow);
    };
  }

  posesSent() {
    return Object.values(this.topics.posesSent).reduce((sum, count) => sum + count, 0);
  }
}

function keep(values, value) {
  values.push(value);
  if (values.length > FRAMES_KEPT) values.shift();
}

const times = new FrameTimes(page.view.renderer, page.loop, page.topics);
page.view.renderer.setAnimationLoop(times.timed((time, frame) => page.loop.step(time, frame)));
window.vrFrameTime = times;
