// An emulated Meta Quest 3 (IWER, Meta's WebXR emulation runtime) in place of a headset: loaded only when the
// page's server runs with --emulate-headset (tests, and trying the page at a desk). The test drives it through
// window.emulatedHeadset: controllers' positions, the trigger and the buttons.
import { P_SPACE, XRDevice, metaQuest3 } from '/vendor/iwer/build/iwer.module.js';

const device = new XRDevice(metaQuest3);
device.installRuntime({ forceInstall: true }); // in place of the browser's own (Chromium has one, without a headset)
// IWER marks the poses of every space but the viewer's as emulatedPosition (its spaces say "emulated": of an
// emulated device), which WebXR keeps for a position the runtime made up, a controller that lost its tracking; the
// page sends no pose of such a controller. The emulated controllers are tracked as a headset tracks them: said so.
for (const controller of Object.values(device.controllers)) {
  const { targetRaySpace, gripSpace } = controller.inputSource;
  for (const space of [targetRaySpace, gripSpace]) if (space) space[P_SPACE].emulated = false;
}
window.emulatedHeadset = device;
