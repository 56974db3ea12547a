// The headset's immersive session: the Enter VR button, entering and leaving, and the trigger (WebXR's selectstart,
// either hand). The runtime reads the controllers at each frame's start and fires the event then: the event's time
// is the reading that first saw the trigger, from which the page measures the press's input delay (presses.js).
export class Headset {
  // xr: three.js's WebXR manager (renderer.xr); button: Enter VR; statusLine: where a failure to enter is said;
  // onTrigger(readMs): a trigger was pressed, and read at readMs (the event's time, performance.now()'s clock).
  constructor(xr, button, statusLine, onTrigger) {
    this.xr = xr;
    this.button = button;
    this.statusLine = statusLine;
    this.onTrigger = onTrigger;
    this.inSession = false;
    this.triggers = 0; // presses of a trigger
    this.error = '';
    button.addEventListener('click', () => {
      this.enter().catch((error) => {
        this.error = `could not enter VR: ${error}`;
        statusLine.textContent = this.error;
      });
    });
  }

  // Enable Enter VR when this browser has immersive VR, else say so.
  async offer() {
    if (navigator.xr && (await navigator.xr.isSessionSupported('immersive-vr'))) {
      this.button.disabled = false;
    } else {
      this.statusLine.textContent = "This browser has no WebXR: open this page in the headset's browser.";
    }
  }

  async enter() {
    const session = await navigator.xr.requestSession('immersive-vr', { optionalFeatures: ['local-floor'] });
    session.addEventListener('selectstart', (event) => {
      this.triggers += 1;
      this.onTrigger(event.timeStamp);
    });
    session.addEventListener('end', () => {
      this.inSession = false;
      this.button.disabled = false;
    });
    await this.xr.setSession(session);
    this.inSession = true;
    this.button.disabled = true;
  }
}
