// One frame of the page, at the headset's frame rate (or the browser's, outside the session): the robot posed by its
// latest joint state, the controllers read as the participant's answers, the participant's tracked body sent during
// a trial of a condition the page tracks, the panel, and both eyes drawn. The session's first frames are the rest
// (rest.js): the participant holds still, the panel says so, the controllers answer nothing, and at its end the
// bodies' jitter goes into the page's announcement as a pose source.
import { frameStamp } from './poses.js';
import { restWords } from './rest.js';

export class FrameLoop {
  // The page's parts: view (scene.js), robot, panel, controllers, tracking (the headset's and the controllers'
  // poses, tracking.js), participant (study.js), topics (ROS); rest (rest.js) and restSays (the settings' words for
  // it), or null: the page tracks no condition, and has no jitter to measure.
  constructor({ view, robot, panel, controllers, tracking, participant, topics, rest = null, restSays = null }) {
    Object.assign(this, { view, robot, panel, controllers, tracking, participant, topics, rest, restSays });
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
    const resting = Boolean(frame) && this.restFrame(time, frame);
    // at rest the controllers are read all the same, so that a press then is not taken for an answer after it
    if (frame && resting) this.controllers.read(frame);
    else if (frame) this.answer(frame);
    if (frame && this.sendPoses) this.sendBody(time, frame);
    if (resting) {
      const [title, lines] = restWords(this.restSays, this.rest.seconds, this.rest.secondsLeft(time));
      this.panel.show(title, lines, 'rest');
    } else {
      this.showInstructions();
    }
    this.view.render();
  }

  // The rest's frame: each tracked body's position kept; true while it goes on. The frame that ends it hands the
  // bodies' jitter to the topics, which announce it.
  restFrame(time, frame) {
    if (!this.rest || this.rest.done) return false;
    if (this.rest.frame(time, this.tracking.read(frame))) return true;
    this.topics.measured(this.rest.seconds, this.rest.jitters());
    return false;
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
  // Only a trial of a condition the page tracks: another tracker may be that of the other condition.
  sendBody(time, frame) {
    if (!this.participant.inTrial || !this.topics.tracks(this.participant.status.condition)) return;
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
