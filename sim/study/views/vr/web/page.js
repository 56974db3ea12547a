// The VR condition's page: the robot from its URDF, the table and the hand in the headset, moved by the robot's
// joint states at the headset's frame rate; the trial's phase and instructions on a panel in view; the trigger,
// buttons and controllers as the participant's answers (study.js). It is a client of the endpoint's WebSocket
// transport (connection.js), reached through this page's own server at /ros.

import * as THREE from 'three';
import { MTLLoader } from 'three/examples/jsm/loaders/MTLLoader.js';
import { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js';
import URDFLoader from 'urdf-loader/URDFLoader.js';
import { RosConnection } from './connection.js';
import { EMPTY, decodeJointState, decodeString, encodeFloat32, encodeHeader, encodeString, rosTime } from './rostcp.js';
import { ControllerEdges, Participant } from './study.js';

const FRAMES_KEPT = 600;

const settings = await (await fetch('/settings.json')).json();
const statusLine = document.getElementById('status');
const enterButton = document.getElementById('enter');

// What tests and the frame-time bench read (window.vrPage).
const page = {
  connection: null,
  renderer: null,
  participant: new Participant(settings.protocol),
  robotLoaded: false,
  meshesLoaded: false,
  inSession: false,
  jointStates: 0, // received
  joints: null, // the latest joint state: {stamp, names, positions, ...}
  frames: 0, // of the immersive session
  triggers: 0, // presses of a trigger
  actions: [], // [what, value] sent, oldest first
  frameIntervals: [], // ms between the session's frames
  frameWork: [], // ms of each frame's update and rendering (rendering waited for with ?frametime)
  error: '',
};
window.vrPage = page;
// ?frametime: each frame waits for its rendering to end, by reading one pixel back (Chromium's gl.finish() returns
// before its GPU process has drawn)
const measureWork = new URLSearchParams(location.search).has('frametime');
const onePixel = new Uint8Array(4);

// --- the scene: the ROS world (x forward, z up) turned to three.js's y up, the participant's eyes at the origin of
// the headset's 'local' space, facing the hand
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.xr.enabled = true;
renderer.xr.setReferenceSpaceType('local');
document.body.appendChild(renderer.domElement);
page.renderer = renderer; // its render info: triangles drawn

const scene = new THREE.Scene();
scene.background = new THREE.Color(0xdfe6ee);
scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(1, 3, 1);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(70, window.innerWidth / window.innerHeight, 0.05, 20);
scene.add(camera);

const world = new THREE.Group();
world.rotation.x = -Math.PI / 2; // ROS (x, y, z) -> three (x, z, -y)
const [seatX, seatY, seatZ] = settings.seat;
world.position.set(-seatX, -seatZ, seatY);
scene.add(world);

function box(spec, colour) {
  const mesh = new THREE.Mesh(
    new THREE.BoxGeometry(...spec.size),
    new THREE.MeshLambertMaterial({ color: new THREE.Color(...colour.map((c) => c / 255)) }),
  );
  mesh.position.set(...spec.xyz);
  mesh.rotation.z = spec.yaw;
  world.add(mesh);
  return mesh;
}
box(settings.table, settings.colours.table);
box(settings.hand, settings.colours.hand);

// --- the robot: urdf-loader, with OBJ meshes (and their .mtl) loaded here, as urdf-loader knows only STL and DAE
const manager = new THREE.LoadingManager();
manager.onLoad = () => {
  page.meshesLoaded = page.robotLoaded;
};
function loadMesh(path, loadingManager, material, done) {
  if (!/\.obj$/i.test(path)) {
    urdfLoader.defaultMeshLoader(path, loadingManager, material, done);
    return;
  }
  loadingManager.itemStart(path);
  fetch(path)
    .then((response) => (response.ok ? response.text() : Promise.reject(new Error(`${path}: ${response.status}`))))
    .then(async (text) => {
      const objLoader = new OBJLoader(loadingManager);
      const library = /^mtllib\s+(.+)$/m.exec(text);
      let materials = null;
      if (library) {
        const folder = path.slice(0, path.lastIndexOf('/') + 1);
        try {
          materials = await new MTLLoader(loadingManager).setPath(folder).loadAsync(library[1].trim());
          materials.preload();
          objLoader.setMaterials(materials);
        } catch (error) {
          console.warn(
            `${path}: its material library ${library[1].trim()} did not load (${error}); the URDF's colour is used`,
          );
        }
      }
      const object = objLoader.parse(text);
      if (!materials && material) object.traverse((child) => child.isMesh && (child.material = material));
      done(object);
    })
    .catch((error) => done(null, error))
    .finally(() => loadingManager.itemEnd(path));
}
const urdfLoader = new URDFLoader(manager);
urdfLoader.loadMeshCb = loadMesh;
let robot = null;
urdfLoader.load(
  settings.robot.urdf,
  (loaded) => {
    robot = loaded;
    robot.position.set(...settings.robot.base.xyz);
    robot.quaternion.set(...settings.robot.base.quaternion_xyzw);
    world.add(robot);
    page.robotLoaded = true;
  },
  undefined,
  (error) => {
    page.error = `the robot's URDF did not load: ${error}`;
  },
);

// --- the panel in view: above and beyond the hand, facing the participant
const panelCanvas = document.createElement('canvas');
panelCanvas.width = 1024;
panelCanvas.height = 384;
const panelTexture = new THREE.CanvasTexture(panelCanvas);
panelTexture.colorSpace = THREE.SRGBColorSpace;
const panel = new THREE.Mesh(
  new THREE.PlaneGeometry(0.8, 0.3),
  new THREE.MeshBasicMaterial({ map: panelTexture, transparent: true }),
);
panel.position.set(0.0, 0.12, -1.3);
scene.add(panel);
let panelText = '';

function drawPanel(connectionState) {
  const [title, lines] = page.participant.instructions();
  const all = page.connection && page.connection.connected ? lines : [...lines, `(${connectionState})`];
  const text = [title, ...all].join('\n');
  if (text === panelText) return;
  panelText = text;
  const context = panelCanvas.getContext('2d');
  context.clearRect(0, 0, panelCanvas.width, panelCanvas.height);
  context.fillStyle = 'rgba(20, 28, 40, 0.85)';
  context.fillRect(0, 0, panelCanvas.width, panelCanvas.height);
  context.fillStyle = '#ffffff';
  context.font = 'bold 56px sans-serif';
  context.fillText(title, 40, 80);
  context.font = '40px sans-serif';
  all.forEach((line, k) => context.fillText(line, 40, 150 + 56 * k));
  panelTexture.needsUpdate = true;
  statusLine.textContent = `${text}\n[${page.participant.phase}]`;
}

// --- the controllers: a small pointer at each tip, so the participant sees where the tips are
for (const index of [0, 1]) {
  const controller = renderer.xr.getController(index);
  const tip = new THREE.Mesh(
    new THREE.ConeGeometry(0.012, 0.06, 16).rotateX(-Math.PI / 2),
    new THREE.MeshLambertMaterial({ color: 0x3050ff }),
  );
  tip.position.z = 0.03;
  controller.add(tip);
  scene.add(controller);
}

// --- ROS
const topics = settings.topics;
const connection = new RosConnection(
  `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${settings.ros_path}`,
  (state) => {
    connectionState = state;
  },
);
let connectionState = 'connecting';
page.connection = connection;
let latestJoints = null;
let appliedJoints = null;
connection.subscribe(topics.joint_states[0], topics.joint_states[1], (payload) => {
  latestJoints = decodeJointState(payload);
  page.joints = latestJoints;
  page.jointStates += 1;
});
connection.subscribe(topics.trial[0], topics.trial[1], (payload) => {
  page.participant.onStatus(JSON.parse(decodeString(payload)));
});
for (const name of Object.keys(settings.protocol.inputs)) connection.advertise(...topics[name]);
connection.open();

let stopSeq = 0;
function act(action) {
  if (!action) return;
  const [what, value] = action;
  const payload = {
    go: () => EMPTY,
    stop: () => encodeHeader(stopSeq++, rosTime(value), settings.stop_source),
    distance: () => encodeFloat32(value),
    preference: () => encodeString(value),
  }[what]();
  if (connection.publish(topics[what][0], payload)) page.actions.push([what, value]);
}

// --- the frame loop
const edges = new Map(); // handedness -> ControllerEdges
let lastFrameAt = null;

// The controllers' tips first, then their buttons: a confirm on either hand measures between both tips.
function readControllers(frame) {
  const session = renderer.xr.getSession();
  const space = renderer.xr.getReferenceSpace();
  const controllers = [...session.inputSources].filter((source) => source.gamepad);
  const tips = controllers.map((source) => frame.getPose(source.targetRaySpace, space)).filter(Boolean);
  const [a, b] = tips.map((pose) => pose.transform.position);
  const distance = tips.length === 2 ? Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z) : null;
  for (const source of controllers) {
    if (!edges.has(source.handedness)) edges.set(source.handedness, new ControllerEdges());
    const buttons = source.gamepad.buttons.map((button) => button.pressed);
    const { confirm, choose } = edges.get(source.handedness).update(buttons, source.gamepad.axes);
    if (choose) page.participant.onChoose(choose);
    if (confirm) act(page.participant.onConfirm(distance));
  }
}

function onFrame(time, frame) {
  const started = performance.now();
  if (frame) page.frames += 1;
  if (frame && lastFrameAt !== null) {
    page.frameIntervals.push(time - lastFrameAt);
    if (page.frameIntervals.length > FRAMES_KEPT) page.frameIntervals.shift();
  }
  lastFrameAt = frame ? time : null;
  if (robot && latestJoints !== appliedJoints) {
    latestJoints.names.forEach((name, k) => robot.setJointValue(name, latestJoints.positions[k]));
    appliedJoints = latestJoints;
  }
  if (frame) readControllers(frame);
  drawPanel(connectionState);
  renderer.render(scene, camera);
  if (frame) {
    if (measureWork) {
      const gl = renderer.getContext();
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, onePixel);
    }
    page.frameWork.push(performance.now() - started);
    if (page.frameWork.length > FRAMES_KEPT) page.frameWork.shift();
  }
}
renderer.setAnimationLoop(onFrame);

window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

// --- entering the headset's session
async function enter() {
  const session = await navigator.xr.requestSession('immersive-vr', { optionalFeatures: ['local-floor'] });
  session.addEventListener('selectstart', () => {
    page.triggers += 1;
    act(page.participant.onTrigger(connection.rosNow()));
  });
  session.addEventListener('end', () => {
    page.inSession = false;
    enterButton.disabled = false;
  });
  await renderer.xr.setSession(session);
  page.inSession = true;
  enterButton.disabled = true;
}
enterButton.addEventListener('click', () => {
  enter().catch((error) => {
    page.error = `could not enter VR: ${error}`;
    statusLine.textContent = page.error;
  });
});
if (navigator.xr && (await navigator.xr.isSessionSupported('immersive-vr'))) {
  enterButton.disabled = false;
} else {
  statusLine.textContent = "This browser has no WebXR: open this page in the headset's browser.";
}
