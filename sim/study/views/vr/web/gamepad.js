// The stop button's presses, from the Gamepad API's snapshots (navigator.getGamepads(), read once an animation
// frame): any button of any gamepad, a foot pedal or a USB button among them, counts. A press is a button's edge
// from released to pressed between two readings. Pure: the page hands it the snapshots, node hands it plain objects.
//
// Its input delay (presses.js's inputDelay): the Gamepad API's `timestamp` is when the browser's poll last saw the
// gamepad's input change, on the clock of performance.now(); the page reads it at `nowMs`, on the same clock, and
// stamps the press then. Their difference is what the page's frame added between the first reading and the stamp.
import { inputDelay } from './presses.js';

export class GamepadPresses {
  constructor() {
    this.held = new Map(); // gamepad index -> [id, pressed flags by button]
  }

  // gamepads: navigator.getGamepads()'s list (null where none is); nowMs: performance.now() of this reading.
  // Returns this reading's presses: [{gamepad (its id), index (its place), control (its button's index), inputDelay
  // (s or null)}]. A gamepad seen for the first time, or another one in its place, has no press yet: a button held
  // while it was plugged in is not a press.
  update(gamepads, nowMs) {
    const presses = [];
    const seen = new Set();
    for (const pad of gamepads || []) {
      if (!pad || pad.connected === false) continue;
      seen.add(pad.index);
      const pressed = pad.buttons.map((control) => Boolean(control.pressed));
      const before = this.held.get(pad.index);
      if (before && before[0] === pad.id) {
        pressed.forEach((down, control) => {
          if (down && !before[1][control]) {
            presses.push({ gamepad: pad.id, index: pad.index, control, inputDelay: inputDelay(nowMs, pad.timestamp) });
          }
        });
      }
      this.held.set(pad.index, [pad.id, pressed]);
    }
    for (const index of [...this.held.keys()]) if (!seen.has(index)) this.held.delete(index);
    return presses;
  }

  // The gamepads seen in the last reading: their ids, by index.
  get connected() {
    return [...this.held.entries()].map(([index, [id]]) => ({ index, id }));
  }
}
