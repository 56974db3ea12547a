// An emulated gamepad (a foot pedal with a few buttons) in place of a real one: loaded only when the button page's
// server runs with --emulate-gamepad (tests, and trying the page without a pedal). Chromium has no virtual gamepad,
// so navigator.getGamepads() is replaced: it returns this pad, a fresh snapshot each call as browsers do. The test
// drives it through window.emulatedGamepad; each change of a button is stamped on performance.now()'s clock, as a
// browser stamps a real gamepad's. A press is held until a reading has reported it (study.js): released before
// the page's next reading, it would have been lost.
import { HeldUntilRead } from './study.js';

const CONTROLS = 4;

const pad = {
  id: 'Emulated foot pedal',
  index: 0,
  connected: false,
  mapping: '',
  timestamp: 0,
  axes: [],
  buttons: Array.from({ length: CONTROLS }, () => ({ pressed: false, touched: false, value: 0 })),
};
const held = Array.from({ length: CONTROLS }, () => new HeldUntilRead(false));
const releasedAt = Array.from({ length: CONTROLS }, () => null); // a release held back: when it happened (ms)

function button(down) {
  return { pressed: down, touched: down, value: down ? 1 : 0 };
}

// A reading: each button as held; a release held back until this reading reported its press applies after it,
// stamped when it happened.
function snapshot() {
  const buttons = held.map((control) => button(control.read()));
  const taken = { ...pad, axes: [...pad.axes], buttons };
  held.forEach((control, k) => {
    if (releasedAt[k] !== null && !control.value) {
      pad.timestamp = Math.max(pad.timestamp, releasedAt[k]);
      releasedAt[k] = null;
    }
  });
  pad.buttons = held.map((control) => button(control.value));
  return taken;
}

Object.defineProperty(navigator, 'getGamepads', {
  configurable: true,
  value: () => [pad.connected ? snapshot() : null, null, null, null],
});

function change(control, down) {
  const now = performance.now();
  held[control].set(down);
  if (held[control].value === down) {
    pad.timestamp = now;
    releasedAt[control] = null;
  } else {
    releasedAt[control] = now; // released before any reading saw the press: stamped once it applies
  }
  pad.buttons[control] = button(held[control].value);
  return now;
}

window.emulatedGamepad = {
  pad,
  // Plug it in: the page is told, as a browser tells it of a real one (after its first press).
  connect() {
    pad.connected = true;
    pad.timestamp = performance.now();
    window.dispatchEvent(new Event('gamepadconnected'));
  },
  // Press or release button `control`; the change's time (ms, performance.now()).
  press(control) {
    return change(control, true);
  },
  release(control) {
    return change(control, false);
  },
};
