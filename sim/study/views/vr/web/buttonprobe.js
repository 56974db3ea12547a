// The tests' view into the button page (window.buttonPage): served and loaded only with the page server's
// --emulate-gamepad, never on the participant's machine.
import { page } from './button.js';

window.buttonPage = {
  page, // every part, for what the tests drive

  // What the tests wait on and check, as plain data.
  state() {
    const status = page.participant.status;
    const best = page.connection.clock.best();
    return {
      connected: page.connected,
      gamepads: page.gamepads.connected.map((pad) => pad.id),
      index: status ? status.index : null,
      phase: status ? status.phase : null,
      counts: page.counts,
      presses: page.presses,
      readings: page.readings,
      longestGapMs: page.longestGapMs,
      clockRoundTripMs: best ? best[0] : null,
      shown: document.body.innerText,
    };
  },
};
