// An emulated gamepad (a foot pedal with a few buttons) in place of a real one: loaded only when the button page's
// server runs with --emulate-gamepad (tests, and trying the page without a pedal). Chromium has no virtual gamepad,
// so navigator.getGamepads() is replaced: it returns this pad, a fresh snapshot each call as browsers do. The test
// drives it through window.emulatedGamepad; each change of a button is stamped on performance.now()'s clock, as a
// browser stamps a real gamepad's.
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

function snapshot() {
  return { ...pad, axes: [...pad.axes], buttons: pad.buttons.map((control) => ({ ...control })) };
}

Object.defineProperty(navigator, 'getGamepads', {
  configurable: true,
  value: () => [pad.connected ? snapshot() : null, null, null, null],
});

function change(control, down) {
  pad.buttons[control] = { pressed: down, touched: down, value: down ? 1 : 0 };
  pad.timestamp = performance.now();
  return pad.timestamp;
}

window.emulatedGamepad = {
  pad,
  // Plug it in: the page is told, as a browser tells it of a real one (after its first press).
  connect() {
    pad.connected = true;
    pad.timestamp = performance.now();
    window.dispatchEvent(new Event('gamepadconnected'));
  },
  // Press or release button `control`; the change's timestamp (ms, performance.now()).
  press(control) {
    return change(control, true);
  },
  release(control) {
    return change(control, false);
  },
};
