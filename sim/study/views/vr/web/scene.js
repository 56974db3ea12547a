// The scene: the ROS world (x forward, z up) turned to three.js's y up, the participant's eyes at the origin of the
// headset's 'local' space, facing the hand; the table and the hand as boxes in the scene's colours.
import * as THREE from 'three';

export class View {
  // settings: the page's settings (the seat, the table, the hand, their colours); container: the element drawn into.
  constructor(settings, container) {
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    this.renderer.setSize(window.innerWidth, window.innerHeight);
    this.renderer.xr.enabled = true;
    this.renderer.xr.setReferenceSpaceType('local');
    container.appendChild(this.renderer.domElement);

    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xdfe6ee);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(1, 3, 1);
    this.scene.add(sun);
    this.camera = new THREE.PerspectiveCamera(70, window.innerWidth / window.innerHeight, 0.05, 20);
    this.scene.add(this.camera);

    // what is placed in ROS's frame (the robot, the table, the hand) goes in `world`
    this.world = new THREE.Group();
    this.world.rotation.x = -Math.PI / 2; // ROS (x, y, z) -> three (x, z, -y)
    const [seatX, seatY, seatZ] = settings.seat;
    this.world.position.set(-seatX, -seatZ, seatY);
    this.scene.add(this.world);
    this.world.add(box(settings.table, settings.colours.table));
    if (settings.pedestal) this.world.add(box(settings.pedestal, settings.colours.table)); // the robot stands on it
    this.world.add(box(settings.hand, settings.colours.hand));
  }

  resize(width, height) {
    this.camera.aspect = width / height;
    this.camera.updateProjectionMatrix();
    this.renderer.setSize(width, height);
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }
}

// A box of the settings ({size, xyz, yaw}, in ROS's frame) in an RGB colour (0-255).
function box(spec, colour) {
  const mesh = new THREE.Mesh(
    new THREE.BoxGeometry(...spec.size),
    new THREE.MeshLambertMaterial({ color: new THREE.Color(...colour.map((c) => c / 255)) }),
  );
  mesh.position.set(...spec.xyz);
  mesh.rotation.z = spec.yaw;
  return mesh;
}
