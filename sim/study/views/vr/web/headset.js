// The headset's immersive session: the Enter VR button, entering and leaving, and the trigger (WebXR's selectstart,
// either hand).
export class Headset {
  // xr: three.js's WebXR manager (renderer.xr); button: Enter VR; statusLine: where a failure to enter is said;
  // onTrigger(): a trigger was pressed.
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
    session.addEventListener('selectstart', () => {
      this.triggers += 1;
      this.onTrigger();
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
