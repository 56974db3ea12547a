// An emulated Meta Quest 3 (IWER, Meta's WebXR emulation runtime) in place of a headset: loaded only when the
// page's server runs with --emulate-headset (tests, and trying the page at a desk). The test drives it through
// window.emulatedHeadset: controllers' positions, the trigger and the buttons.
import { P_SPACE, XRDevice, metaQuest3 } from '/vendor/iwer/build/iwer.module.js';
import { HeldUntilRead } from './study.js';

const device = new XRDevice(metaQuest3);
device.installRuntime({ forceInstall: true }); // in place of the browser's own (Chromium has one, without a headset)
// IWER marks the poses of every space but the viewer's as emulatedPosition (its spaces say "emulated": of an
// emulated device), which WebXR keeps for a position the runtime made up, a controller that lost its tracking; the
// page sends no pose of such a controller. The emulated controllers are tracked as a headset tracks them: said so.
for (const controller of Object.values(device.controllers)) {
  const { targetRaySpace, gripSpace } = controller.inputSource;
  for (const space of [targetRaySpace, gripSpace]) if (space) space[P_SPACE].emulated = false;
  holdUntilRead(controller);
}

// Each button's and thumbstick's change is held until a frame has read it (study.js): IWER applies a button's
// latest value at the next frame's start, and its thumbstick's at once, so a press or a push that ended before the
// next frame was lost. They reach IWER at each frame's start, before it applies them.
function holdUntilRead(controller) {
  const setButton = controller.updateButtonValue.bind(controller);
  const setAxes = controller.updateAxes.bind(controller);
  const buttons = new Map(); // id -> HeldUntilRead
  const axes = new Map(); // id -> [HeldUntilRead of x, of y]
  controller.updateButtonValue = (id, value) => {
    if (!buttons.has(id)) buttons.set(id, new HeldUntilRead());
    buttons.get(id).set(value);
  };
  controller.updateAxes = (id, x, y) => {
    if (!axes.has(id)) axes.set(id, [new HeldUntilRead(), new HeldUntilRead()]);
    const [heldX, heldY] = axes.get(id);
    heldX.set(x);
    heldY.set(y);
  };
  const frameStart = controller.onFrameStart.bind(controller);
  controller.onFrameStart = (frame) => {
    for (const [id, held] of buttons) setButton(id, held.read());
    for (const [id, [heldX, heldY]] of axes) setAxes(id, heldX.read(), heldY.read());
    frameStart(frame);
  };
}

window.emulatedHeadset = device;
