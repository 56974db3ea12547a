// The reality condition's stop button: any USB button, foot pedal or gamepad, read through the browser's Gamepad API
// once an animation frame (gamepad.js). A press while the trial's phase accepts a stop goes to the runner like the VR
// page's trigger: a std_msgs/Header on the stop topic, stamped on the runner's clock (from the endpoint's pings,
// clock.js), named by the condition's stop source, its input delay in its seq (presses.js). The page shows, large:
// whether ROS is connected, which gamepads it sees, the trial's phase, whether a press now would count, and each
// press's timing. The phases, topics and stop source are the trial protocol's table, from the settings.
//
// Once its settings have come (by the cookie that keeps the launch's key), the key leaves the page's address
// (address.js).
//
// `page` holds its whole state; the tests' probe imports it, served only when the server is started for it.
import { forgetKey } from './address.js';
import { RosConnection, browserClockMs } from './connection.js';
import { GamepadPresses } from './gamepad.js';
import { stopPayload } from './presses.js';
import { decodeString } from './rostcp.js';
import { Participant } from './study.js';

const PRESSES_SHOWN = 8;

class ButtonPage {
  constructor(settings, url) {
    this.settings = settings;
    this.participant = new Participant(settings.protocol); // the trial's phase, what it accepts, a press's stamp
    this.state = 'connecting';
    this.connection = new RosConnection(url, (state) => {
      this.state = state;
    });
    const [statusTopic, statusType] = settings.topics.trial;
    this.connection.subscribe(statusTopic, statusType, (payload) => {
      this.participant.onStatus(JSON.parse(decodeString(payload)));
    });
    this.connection.advertise(...settings.topics.stop);
    this.connection.announceClock(...settings.topics.page_clock, settings.stop_source); // for the runner to judge
    this.gamepads = new GamepadPresses();
    // every press, oldest first: {gamepad, control, inputDelay, readingGap, stamp, clockOffset, phase, index, sent};
    // readingGap (s) since the reading before the one that saw it: the input changed within it, so it bounds the input
    // delay; clockOffset (s) the one the stamp was read with (null without ROS time)
    this.presses = [];
    this.readings = 0; // of the gamepads, one an animation frame
    this.longestGapMs = 0; // between two readings: the most a press can wait to be seen
    this.lastReadingMs = null;
  }

  // One reading of the gamepads, at nowMs (performance.now()).
  read(gamepads, nowMs) {
    this.readings += 1;
    const gap = this.lastReadingMs === null ? null : (nowMs - this.lastReadingMs) / 1000;
    if (gap !== null) this.longestGapMs = Math.max(this.longestGapMs, gap * 1000);
    this.lastReadingMs = nowMs;
    for (const press of this.gamepads.update(gamepads, nowMs)) this.press(press, gap, nowMs);
  }

  // A press read at readMs (performance.now()): sent when the phase accepts a stop (stamped on ROS time at readMs,
  // where its input delay ends, or 0 without a clock offset), else only shown.
  press({ gamepad, control, inputDelay }, readingGap, readMs) {
    const reading = this.connection.rosReading(browserClockMs(readMs));
    const action = this.participant.onTrigger(reading === null ? null : reading.ros);
    const status = this.participant.status;
    const press = {
      gamepad,
      control,
      inputDelay,
      readingGap,
      stamp: action ? action[1] : null,
      clockOffset: reading === null ? null : reading.offset,
      phase: this.participant.phase,
      index: status ? status.index : null,
      sent: false,
    };
    if (action) {
      const payload = stopPayload(action[1], inputDelay, this.settings.stop_source);
      press.sent = this.connection.publish(this.settings.topics.stop[0], payload);
    }
    this.presses.push(press);
  }

  get connected() {
    return this.connection.connected;
  }

  // Whether a press now would stop the robot.
  get counts() {
    return this.participant.accepts === 'stop' && this.connected;
  }
}

function ms(seconds) {
  return seconds === null ? 'not measured' : `${(seconds * 1000).toFixed(1)} ms`;
}

function light(element, text, kind) {
  if (element.textContent !== text) element.textContent = text;
  element.className = `light ${kind}`;
}

// What the page shows, from its state: written only where it changed.
function show(page, elements) {
  light(elements.ros, page.connected ? 'ROS: connected' : `ROS: ${page.state}`, page.connected ? 'good' : 'bad');
  const pads = page.gamepads.connected;
  light(
    elements.gamepad,
    pads.length ? `Gamepad: ${pads.map((pad) => pad.id).join(', ')}` : 'No gamepad: press the button once',
    pads.length ? 'good' : 'bad',
  );
  const status = page.participant.status;
  const phase = status ? page.participant.phases.get(status.phase) : undefined;
  const trial = status
    ? `${status.index ? `Trial ${status.index} of ${status.total}` : 'Session'}: ${status.phase}` +
      (phase ? `\n${phase.meaning}` : '')
    : 'Waiting for the study';
  if (elements.trial.textContent !== trial) elements.trial.textContent = trial;
  if (page.counts) light(elements.counts, 'A press now STOPS the robot', 'good');
  else light(elements.counts, 'A press now would not count', 'idle');
  const best = page.connection.clock.best();
  const clock = best
    ? `Stamps on the runner's clock by the endpoint's pings (best round trip ${best[0].toFixed(1)} ms). ` +
      `Presses are named ${page.settings.stop_source}.`
    : "No ROS time yet: a press would be stamped 0 (taken when it arrives). Is the runner's /clock running?";
  if (elements.clock.textContent !== clock) elements.clock.textContent = clock;
  const shown = page.presses.slice(-PRESSES_SHOWN).reverse();
  const lines = shown.map(
    (p) =>
      `${p.sent ? 'SENT' : 'not sent'} | trial ${p.index ?? '-'} ${p.phase} | ${p.gamepad} #${p.control} | ` +
      `input delay ${ms(p.inputDelay)} (read ${ms(p.readingGap)} after the last reading) | stamp ${p.stamp === null ? '-' : p.stamp.toFixed(3)} s`,
  );
  if (elements.presses.dataset.text !== lines.join('\n')) {
    elements.presses.dataset.text = lines.join('\n');
    elements.presses.replaceChildren(
      ...lines.map((line) => Object.assign(document.createElement('li'), { textContent: line })),
    );
  }
}

async function startPage() {
  const settings = await (await fetch('/settings.json')).json();
  forgetKey(location, history, settings.key_parameter); // the settings came by the cookie: the key is not needed
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${settings.ros_path}`;
  const page = new ButtonPage(settings, url);
  page.connection.open();
  const elements = Object.fromEntries(
    ['ros', 'gamepad', 'trial', 'counts', 'clock', 'presses'].map((id) => [id, document.getElementById(id)]),
  );
  // A browser shows a gamepad to a page only once one of its buttons has been pressed; the event says so at once.
  window.addEventListener('gamepadconnected', () => page.read(navigator.getGamepads(), performance.now()));
  const frame = () => {
    page.read(navigator.getGamepads(), performance.now());
    show(page, elements);
    requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  return page;
}

export const page = await startPage();
