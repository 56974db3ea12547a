// What the participant's controls mean in each phase of a trial, and what the page says to them: the study's
// rules for the headset, without three.js or a socket, so node runs them for the tests. The phases, the input each
// accepts, the panel's words and the limits are the trial protocol's table (sim/study/run/protocol.json), which the
// page gets with its settings: nothing of it is typed here.
//
//   trigger (either hand)         the phase's stop, when it accepts one
//   A or X                        the phase's go, distance (between the controllers' tips), preference (the path
//                                 shown) or answer (the point of the item's scale shown), whichever it accepts
//   thumbstick left / right       while a preference is asked: show the previous / next path of the group; while a
//                                 questionnaire's item is asked: one point down / up its scale, stopping at its ends;
//                                 an item starts with no answer chosen, and the first push enters the scale from the
//                                 end it comes from: right, its lowest point; left, its highest (firstAnswer)

// An action is [input, value]: ['stop', stamp s or 0], ['go'], ['distance', m], ['preference', path name],
// ['answer', {administration, item, answer}], named by the table's inputs.
export class Participant {
  constructor(protocol) {
    this.protocol = protocol;
    this.phases = new Map(protocol.phases.map((phase) => [phase.name, phase]));
    this.status = null;
    this.choice = 0; // the group's path shown while a preference is asked
    this.answer = null; // the point of the item's scale chosen while a questionnaire's item is asked; null: none yet
    this.answered = false; // this phase's answer has been sent
    this.notice = ''; // why the last confirm did nothing
  }

  onStatus(status) {
    // a questionnaire asks item after item in one phase: each item is a phase of its own for the answer
    const samePhase =
      this.status &&
      this.status.index === status.index &&
      this.status.phase === status.phase &&
      this.status.administration === status.administration &&
      this.status.item === status.item;
    this.status = status;
    if (!samePhase) {
      this.answered = false;
      this.notice = '';
      if (this.accepts === 'preference') this.choice = 0;
      if (this.accepts === 'answer') this.answer = null; // no default: paper and the keyboard have none either
    } else if (this.accepts === 'answer' && this.answered) {
      // the runner says an item again only when it refused the answer it got (off the scale, or to another item):
      // it still waits, so the page asks again, from the point last shown
      this.answered = false;
      this.notice = 'That answer was not taken: please answer again.';
    }
  }

  get phase() {
    return this.status ? this.status.phase : 'waiting';
  }

  // The input the current phase accepts (the table's), or null.
  get accepts() {
    const phase = this.status ? this.phases.get(this.status.phase) : undefined;
    return phase ? phase.accepts : null;
  }

  // The status is a trial's, whose poses the page sends (the protocol's poses): a trial has its test (1 or 2); a
  // questionnaire's item, between trials, and the end (index 0) have none. Their phases are checked too, by what
  // the table says of them rather than by name: a questionnaire's accepts an answer, the end has index 0.
  get inTrial() {
    const status = this.status;
    return Boolean(status) && status.test > 0 && status.index > 0 && this.accepts !== 'answer';
  }

  // The trigger was pressed; rosNow is ROS time by the measured clock offset (s), or null without one.
  onTrigger(rosNow) {
    if (this.accepts !== 'stop') return null;
    return ['stop', this.stampFor(rosNow)];
  }

  // A press's stamp: ROS time when the clock offset is known and agrees with the runner's clock (within the table's
  // stamp window around the motion's start), else 0 ("when it arrives"). An endpoint without /use_sim_time answers
  // pings with the wall clock, not the runner's.
  stampFor(rosNow) {
    const start = this.status ? this.status.motion_start : null;
    if (rosNow === null || typeof start !== 'number') return 0;
    const [before, after] = this.protocol.limits.stamp_window_s;
    return rosNow >= start + before && rosNow <= start + after ? rosNow : 0;
  }

  // A or X was pressed; controllersDistance: between the two controllers' tips (m), or null when not both tracked.
  onConfirm(controllersDistance) {
    if (this.answered) return null;
    const accepts = this.accepts;
    if (accepts === 'go') {
      this.answered = true;
      return ['go'];
    }
    if (accepts === 'distance') {
      const most = this.protocol.limits.max_perceived_distance_m;
      if (controllersDistance === null) {
        this.notice = 'Hold both controllers where you see them';
        return null;
      }
      if (!(controllersDistance >= 0 && controllersDistance <= most)) {
        this.notice = `Keep the controllers within ${most} m of each other`;
        return null;
      }
      this.answered = true;
      this.notice = '';
      return ['distance', controllersDistance];
    }
    if (accepts === 'preference') {
      const paths = this.status.group_paths;
      if (paths.length === 0) return null;
      this.answered = true;
      return ['preference', paths[this.choice]];
    }
    if (accepts === 'answer') {
      if (this.answer === null) {
        this.notice = 'Choose an answer with the thumbstick first.';
        return null;
      }
      this.answered = true;
      this.notice = '';
      // the answer names its item, so that the runner never takes a late one for the next item's
      const { administration, item } = this.status;
      return ['answer', { administration, item, answer: this.answer }];
    }
    return null;
  }

  // The thumbstick was pushed left (-1) or right (+1): one step per push (ControllerEdges gives a held push once).
  onChoose(step) {
    if (this.answered) return;
    if (this.accepts === 'preference') {
      const count = this.status.group_paths.length;
      if (count > 0) this.choice = (this.choice + step + count) % count;
    } else if (this.accepts === 'answer') {
      // a scale stops at its ends, unlike the group's paths, which go round: from "severe" one more push is not
      // "none"
      const { scale_low: low, scale_high: high } = this.status;
      this.answer =
        this.answer === null ? firstAnswer(this.status, step) : Math.min(high, Math.max(low, this.answer + step));
      this.notice = '';
    }
  }

  // What the panel in view says: a title and lines, the phase's words from the table ({choice} and {path}: the
  // group's path shown; {answer} and {label}: the point of the item's scale chosen and its label, NO_ANSWER and
  // NO_ANSWER_LABEL before one is; any other {name}:
  // the status's field of that name, e.g. a questionnaire's item_text). Placeholders of what the status lacks stay
  // as they are.
  instructions() {
    const status = this.status;
    if (!status) return ['Waiting for the study', ['The experimenter starts the session.']];
    const phase = this.phases.get(status.phase);
    if (!phase) return [`Trial ${status.index} of ${status.total}`, [status.phase]];
    const panel = phase.panel;
    const words = this.answered && panel.answered ? panel.answered : panel.lines;
    const path = status.group_paths[this.choice] || '';
    const answering = this.accepts === 'answer';
    const fill = (line) =>
      line
        .replace('{choice}', String(this.choice + 1))
        .replace('{path}', path)
        .replace('{answer}', answering ? (this.answer === null ? NO_ANSWER : String(this.answer)) : '{answer}')
        .replace(
          '{label}',
          answering ? (this.answer === null ? NO_ANSWER_LABEL : answerLabel(status, this.answer)) : '{label}',
        )
        .replace(/\{(\w+)\}/g, (whole, key) => (status[key] == null ? whole : String(status[key])));
    const title = panel.title ? fill(panel.title) : `Trial ${status.index} of ${status.total}`;
    const lines = words.map(fill);
    return [title, this.notice ? [...lines, this.notice] : lines];
  }
}

// What the panel shows for an item before an answer is chosen.
export const NO_ANSWER = '?';
export const NO_ANSWER_LABEL = 'no answer yet';

// Where the first push of the thumbstick lands on an item's scale, which starts unanswered: the cursor waits just off
// the end the push comes from and steps onto the scale's first point from there, so a push right (+1) lands on the
// lowest point and a push left (-1) on the highest. Starting from the middle put every first push there, and a
// participant who confirmed at once answered "neutral": a pull to the centre. Here no point is where the page puts
// the cursor by itself: which end it enters from is the participant's choice, the two ends alike, and every other
// point is reached only by walking to it (at most half the scale's pushes, from the nearer end). The same rule for
// every scale, so that the page needs to know no instrument; no point is taken without a push and a confirm, as on
// paper nothing is ticked until the participant ticks it.
export function firstAnswer(status, step) {
  return step > 0 ? status.scale_low : status.scale_high;
}

// What the panel says of a point of the item's scale: its label, or, for a point without one (the IPQ labels only
// its ends), where it lies between the labelled points on either side.
export function answerLabel(status, answer) {
  const { scale_low: low, scale_labels: labels } = status;
  const label = (point) => labels[point - low] || '';
  if (label(answer)) return label(answer);
  const points = labels.map((_, k) => low + k).filter((point) => label(point));
  const below = points.filter((point) => point < answer).at(-1);
  const above = points.find((point) => point > answer);
  if (below === undefined || above === undefined) return '';
  return `between ${label(below)} and ${label(above)}`;
}

// The panel's lines broken at spaces to fit its width, as the canvas measures them (a questionnaire's item may run to
// 140 characters, three times what one line of the panel holds); here rather than in panel.js, which needs three.js,
// so that node runs it for the tests.
// lines: the text's lines; width: the most a line may measure; measure(text): what the text measures.
export function wrapped(lines, width, measure) {
  const out = [];
  for (const line of lines) {
    let current = '';
    for (const word of line.split(' ')) {
      const longer = current ? `${current} ${word}` : word;
      if (current && measure(longer) > width) {
        out.push(current);
        current = word; // a word longer than the line stands alone, and the canvas cuts it
      } else {
        current = longer;
      }
    }
    out.push(current);
  }
  return out;
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

// An emulated control (a button's value, a thumbstick's axis) as the runtime that reads it once a frame must see it:
// a change away from rest is held until one reading has reported it. The emulations (emulation.js for the headset,
// gamepademulation.js for the pedal) use it; here beside ControllerEdges, whose readings it feeds, for node's tests.
//
// Why: the page reads the controllers once a frame (WebXR has no event for A, X or the thumbstick, and updates
// their state at each frame's start; the button page reads the Gamepad API once an animation frame). IWER, the
// emulated headset, keeps only a button's latest value until the next frame starts, and the emulated pedal only its
// current one: a press released before the next frame began never reached the page, which sees no edge. With
// software rendering a frame may take from 0.1 s to over a second, longer than a click, so presses were lost (2 of
// 16 questionnaire items in one emulated session). A headset reads its controllers at 72-120 Hz, several times
// within any press of a person; held here, an emulated press reaches the next frame however slow it is, once.
export class HeldUntilRead {
  constructor(rest = 0) {
    this.rest = rest;
    this.value = rest;
    this.unread = false; // a value away from rest that no reading has reported yet
    this.next = null; // the value set back to rest while unread: it applies after the next reading
  }

  // The control changed to `value`.
  set(value) {
    if (this.unread && value === this.rest) {
      this.next = value;
      return;
    }
    this.value = value;
    this.unread = value !== this.rest;
    this.next = null;
  }

  // A reading (a frame's start): the value it reports.
  read() {
    const value = this.value;
    this.unread = false;
    if (this.next !== null) {
      this.value = this.next;
      this.next = null;
    }
    return value;
  }
}
