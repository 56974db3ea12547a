// The participant's controllers: a small pointer at each tip, so the participant sees where the tips are; and, once
// a frame, the tips' distance and what each controller's buttons and thumbstick did since the last frame.
import * as THREE from 'three';
import { ControllerEdges } from './study.js';

export class Controllers {
  // xr: three.js's WebXR manager (renderer.xr); scene: where the pointers go.
  constructor(xr, scene) {
    this.xr = xr;
    this.edges = new Map(); // handedness -> ControllerEdges
    for (const index of [0, 1]) {
      const controller = xr.getController(index);
      const tip = new THREE.Mesh(
        new THREE.ConeGeometry(0.012, 0.06, 16).rotateX(-Math.PI / 2),
        new THREE.MeshLambertMaterial({ color: 0x3050ff }),
      );
      tip.position.z = 0.03;
      controller.add(tip);
      scene.add(controller);
    }
  }

  // In the session's `frame`: {distance between the two tips (m, null unless both are tracked), presses: each
  // controller's {confirm, choose}}. The tips are read before the buttons: a confirm on either hand measures
  // between both tips.
  read(frame) {
    const space = this.xr.getReferenceSpace();
    const controllers = [...this.xr.getSession().inputSources].filter((source) => source.gamepad);
    const tips = controllers.map((source) => frame.getPose(source.targetRaySpace, space)).filter(Boolean);
    const [a, b] = tips.map((pose) => pose.transform.position);
    const distance = tips.length === 2 ? Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z) : null;
    const presses = controllers.map((source) => {
      if (!this.edges.has(source.handedness)) this.edges.set(source.handedness, new ControllerEdges());
      const buttons = source.gamepad.buttons.map((button) => button.pressed);
      return this.edges.get(source.handedness).update(buttons, source.gamepad.axes);
    });
    return { distance, presses };
  }
}
