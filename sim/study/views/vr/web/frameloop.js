// One frame of the page, at the headset's frame rate (or the browser's, outside the session): the robot posed by its
// latest joint state, the controllers read as the participant's answers, the participant's tracked body sent during
// a trial, the panel, and both eyes drawn.
import { frameStamp } from './poses.js';

export class FrameLoop {
  // The page's parts: view (scene.js), robot, panel, controllers, tracking (the headset's and the controllers'
  // poses, tracking.js), participant (study.js) and topics (ROS).
  constructor({ view, robot, panel, controllers, tracking, participant, topics }) {
    Object.assign(this, { view, robot, panel, controllers, tracking, participant, topics });
    this.frames = 0; // of the immersive session
    // Off, no pose is read or sent: the frame-time bench (bench/vr_frame_bench.py) measures frames without them and
    // with them, to show what they cost.
    this.sendPoses = true;
    this.poseFrames = 0; // session frames that sent the tracked body (a trial's, with ROS time known)
    this.timeOrigin = performance.timeOrigin; // when performance.now() was 0, on the browser's clock (ms)
  }

  // three.js's animation loop: `frame` is the session's XRFrame, undefined outside the session.
  step(time, frame) {
    if (frame) this.frames += 1;
    this.robot.update();
    if (frame) this.answer(frame);
    if (frame && this.sendPoses) this.sendBody(time, frame);
    this.showInstructions();
    this.view.render();
  }

  answer(frame) {
    const { distance, presses } = this.controllers.read(frame);
    for (const { confirm, choose } of presses) {
      if (choose) this.participant.onChoose(choose);
      if (confirm) this.topics.send(this.participant.onConfirm(distance));
    }
  }

  // During a trial, each tracked body's pose in this frame, stamped with the frame's time on the runner's clock;
  // nothing before that clock is known (a pose stamped on the browser's clock would be placed wrongly in the trial).
  sendBody(time, frame) {
    if (!this.participant.inTrial) return;
    const stamp = frameStamp(time, this.timeOrigin, this.topics.clockOffset);
    if (stamp === null) return;
    this.poseFrames += 1;
    this.topics.sendPoses(stamp, this.tracking.read(frame), this.participant.status.condition);
  }

  // The phase's instructions, and what the connection does while it is not connected.
  showInstructions() {
    const [title, lines] = this.participant.instructions();
    const shown = this.topics.connected ? lines : [...lines, `(${this.topics.state})`];
    this.panel.show(title, shown, this.participant.phase);
  }
}
