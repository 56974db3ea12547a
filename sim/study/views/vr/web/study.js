// What the participant's controls mean in each phase of a trial, and what the page says to them: the study's
// rules for the headset, without three.js or a socket, so node runs them for the tests. The runner's phases and
// topics are those of sim/study/run/protocol.py.
//
//   trigger (either hand)         stop the robot, while it moves
//   A or X                        ready: start the approach; distance: give the distance between the controllers'
//                                 tips; preference: choose the path shown
//   thumbstick left / right       preference: show the previous / next path of the group

export const STOP_SOURCE = 'webxr_trigger';
export const MAX_PERCEIVED_DISTANCE = 2.0; // m, as the runner checks it
const LONGEST_MOTION_S = 120; // a stamp further from the motion's start than this is on another clock

// An action is [what, value]: ['stop', stamp s or 0], ['go'], ['distance', m], ['preference', path name].
export class Participant {
  constructor() {
    this.status = null;
    this.choice = 0; // the group's path shown in the preference phase
    this.answered = false; // this phase's answer has been sent
    this.notice = ''; // why the last confirm did nothing
  }

  onStatus(status) {
    const samePhase = this.status && this.status.index === status.index && this.status.phase === status.phase;
    this.status = status;
    if (!samePhase) {
      this.answered = false;
      this.notice = '';
      if (status.phase === 'preference') this.choice = 0;
    }
  }

  get phase() {
    return this.status ? this.status.phase : 'waiting';
  }

  // The trigger was pressed; rosNow is ROS time by the measured clock offset (s), or null without one.
  onTrigger(rosNow) {
    if (this.phase !== 'moving') return null;
    return ['stop', this.stampFor(rosNow)];
  }

  // A press's stamp: ROS time when the clock offset is known and agrees with the runner's clock, else 0
  // ("when it arrives"). An endpoint without /use_sim_time answers pings with the wall clock, not the runner's.
  stampFor(rosNow) {
    const start = this.status ? this.status.motion_start : null;
    if (rosNow === null || typeof start !== 'number') return 0;
    return rosNow >= start - 1 && rosNow <= start + LONGEST_MOTION_S ? rosNow : 0;
  }

  // A or X was pressed; controllersDistance: between the two controllers' tips (m), or null when not both tracked.
  onConfirm(controllersDistance) {
    if (this.answered) return null;
    const phase = this.phase;
    if (phase === 'ready') {
      this.answered = true;
      return ['go'];
    }
    if (phase === 'distance') {
      if (controllersDistance === null) {
        this.notice = 'Hold both controllers where you see them';
        return null;
      }
      if (!(controllersDistance >= 0 && controllersDistance <= MAX_PERCEIVED_DISTANCE)) {
        this.notice = `Keep the controllers within ${MAX_PERCEIVED_DISTANCE} m of each other`;
        return null;
      }
      this.answered = true;
      this.notice = '';
      return ['distance', controllersDistance];
    }
    if (phase === 'preference') {
      const paths = this.status.group_paths;
      if (paths.length === 0) return null;
      this.answered = true;
      return ['preference', paths[this.choice]];
    }
    return null;
  }

  // The thumbstick was pushed left (-1) or right (+1).
  onChoose(step) {
    if (this.phase !== 'preference' || this.answered) return;
    const count = this.status.group_paths.length;
    if (count > 0) this.choice = (this.choice + step + count) % count;
  }

  // What the panel in view says: a title and lines.
  instructions() {
    const status = this.status;
    if (!status) return ['Waiting for the study', ['The experimenter starts the session.']];
    if (status.phase === 'done') return ['Thank you', ['The session is over. You may take off the headset.']];
    const title = `Trial ${status.index} of ${status.total}`;
    const lines = {
      to_start: ['The robot moves to its start.'],
      ready: ['Press A (or X) when you are ready.'],
      moving: ['Press the trigger to stop the robot', 'when you want it to stop.'],
      at_rest: ['The robot has stopped.'],
      distance: this.answered
        ? ['Thank you.']
        : ['Show the distance between the robot and the hand', 'with the tips of your two controllers,', 'then press A (or X).'],
      preference: this.answered
        ? ['Thank you.']
        : [
            'Which approach did you prefer?',
            `< ${this.choice + 1}: ${status.group_paths[this.choice] || ''} >`,
            'Thumbstick to change, A (or X) to choose.',
          ],
    }[status.phase] || [status.phase];
    return [title, this.notice ? [...lines, this.notice] : lines];
  }
}

// Button indices of the xr-standard gamepad mapping (Quest Touch: 4 is A on the right hand, X on the left).
export const TRIGGER = 0;
export const PRIMARY_BUTTON = 4;
export const THUMBSTICK_X = 2;
const STICK_PUSHED = 0.6;
const STICK_RELEASED = 0.3;

// Edges of one controller's buttons and thumbstick from frame to frame: what was pressed since the last frame.
export class ControllerEdges {
  constructor() {
    this.primary = false;
    this.stick = 0; // -1, 0, +1 while pushed
  }

  // buttons: pressed flags by index; axes: the gamepad's axes. Returns {confirm, choose (-1, 0 or +1)}.
  update(buttons, axes) {
    const primary = Boolean(buttons[PRIMARY_BUTTON]);
    const confirm = primary && !this.primary;
    this.primary = primary;
    const x = axes.length > THUMBSTICK_X ? axes[THUMBSTICK_X] : 0;
    let choose = 0;
    if (this.stick === 0 && Math.abs(x) >= STICK_PUSHED) {
      this.stick = Math.sign(x);
      choose = this.stick;
    } else if (Math.abs(x) <= STICK_RELEASED) {
      this.stick = 0;
    }
    return { confirm, choose };
  }
}
