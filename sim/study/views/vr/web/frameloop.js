// One frame of the page, at the headset's frame rate (or the browser's, outside the session): the robot posed by its
// latest joint state, the controllers read as the participant's answers, the panel, and both eyes drawn.
export class FrameLoop {
  // The page's parts: view (scene.js), robot, panel, controllers, participant (study.js) and topics (ROS).
  constructor({ view, robot, panel, controllers, participant, topics }) {
    Object.assign(this, { view, robot, panel, controllers, participant, topics });
    this.frames = 0; // of the immersive session
    this.frameTime = null; // the latest session frame's time (ms, performance.now()'s clock)
  }

  // s since the latest session frame began, at nowMs (performance.now()); null outside the session. XR input events
  // carry no time: the runtime reads the controllers once a frame, so this is what a trigger press's input delay can
  // be measured as, the time from the frame whose reading held it (within a frame) to its stamp.
  sinceFrame(nowMs) {
    return this.frameTime === null ? null : Math.max(0, nowMs - this.frameTime) / 1000;
  }

  // three.js's animation loop: `frame` is the session's XRFrame, undefined outside the session.
  step(time, frame) {
    if (frame) this.frames += 1;
    this.frameTime = frame ? time : null;
    this.robot.update();
    if (frame) this.answer(frame);
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

  // The phase's instructions, and what the connection does while it is not connected.
  showInstructions() {
    const [title, lines] = this.participant.instructions();
    const shown = this.topics.connected ? lines : [...lines, `(${this.topics.state})`];
    this.panel.show(title, shown, this.participant.phase);
  }
}
