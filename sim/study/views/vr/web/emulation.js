// An emulated Meta Quest 3 (IWER, Meta's WebXR emulation runtime) in place of a headset: loaded only when the
// page's server runs with --emulate-headset (tests, and trying the page at a desk). The test drives it through
// window.emulatedHeadset: controllers' positions, the trigger and the buttons.
import { XRDevice, metaQuest3 } from '/vendor/iwer/build/iwer.module.js';

const device = new XRDevice(metaQuest3);
device.installRuntime({ forceInstall: true }); // in place of the browser's own (Chromium has one, without a headset)
window.emulatedHeadset = device;
