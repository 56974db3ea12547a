// The panel in view, above and beyond the hand, facing the participant: the trial's phase and what to do. The page's
// status line (outside the headset) says the same, with the phase's name.
import * as THREE from 'three';
import { wrapped } from './study.js';

const WIDTH_PX = 1024;
const HEIGHT_PX = 512; // room for a questionnaire's long item broken over three lines, its answer and a notice
const MARGIN_PX = 40;
const PANEL_WIDTH_M = 0.8;

export class Panel {
  // scene: three.js's scene (the panel stays in view, in the headset's space); statusLine: an element for the text.
  constructor(scene, statusLine) {
    this.statusLine = statusLine;
    this.canvas = document.createElement('canvas');
    this.canvas.width = WIDTH_PX;
    this.canvas.height = HEIGHT_PX;
    this.texture = new THREE.CanvasTexture(this.canvas);
    this.texture.colorSpace = THREE.SRGBColorSpace;
    const mesh = new THREE.Mesh(
      new THREE.PlaneGeometry(PANEL_WIDTH_M, (PANEL_WIDTH_M * HEIGHT_PX) / WIDTH_PX),
      new THREE.MeshBasicMaterial({ map: this.texture, transparent: true }),
    );
    // its lower edge where the 384 px panel had it (y -0.03 m), so that the taller panel hides no more of the robot
    mesh.position.set(0.0, (PANEL_WIDTH_M * HEIGHT_PX) / WIDTH_PX / 2 - 0.03, -1.3);
    scene.add(mesh);
    this.text = ''; // what the panel shows
  }

  // Show a title and lines; the canvas is drawn again only when they changed (once a frame would cost the upload).
  show(title, lines, phase) {
    const text = [title, ...lines].join('\n');
    if (text === this.text) return;
    this.text = text;
    const context = this.canvas.getContext('2d');
    context.clearRect(0, 0, WIDTH_PX, HEIGHT_PX);
    context.fillStyle = 'rgba(20, 28, 40, 0.85)';
    context.fillRect(0, 0, WIDTH_PX, HEIGHT_PX);
    context.fillStyle = '#ffffff';
    context.font = 'bold 56px sans-serif';
    context.fillText(title, MARGIN_PX, 80);
    context.font = '40px sans-serif';
    const broken = wrapped(lines, WIDTH_PX - 2 * MARGIN_PX, (text) => context.measureText(text).width);
    broken.forEach((line, k) => context.fillText(line, MARGIN_PX, 150 + 56 * k));
    this.texture.needsUpdate = true;
    this.statusLine.textContent = `${text}\n[${phase}]`;
  }
}
