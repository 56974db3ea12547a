// The robot from its URDF (urdf-loader), with its OBJ meshes (and their .mtl) loaded here, as urdf-loader knows only
// STL and DAE; posed by the latest joint state, once a frame.
import * as THREE from 'three';
import { MTLLoader } from 'three/examples/jsm/loaders/MTLLoader.js';
import { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js';
import URDFLoader from 'urdf-loader/URDFLoader.js';

export class Robot {
  // spec: the settings' robot ({urdf, base: {xyz, quaternion_xyzw}}); parent: the group in ROS's frame.
  constructor(spec, parent) {
    this.model = null; // urdf-loader's robot, once loaded
    this.loaded = false; // the URDF
    this.meshesLoaded = false; // and every mesh it names
    this.error = '';
    this.latest = null; // the latest joint state received: {stamp, names, positions, ...}
    this.applied = null; // the one the model shows
    this.received = 0; // joint states

    const manager = new THREE.LoadingManager();
    manager.onLoad = () => {
      this.meshesLoaded = this.loaded;
    };
    const loader = new URDFLoader(manager);
    loader.loadMeshCb = (path, loadingManager, material, done) => {
      if (/\.obj$/i.test(path)) loadObj(path, loadingManager, material, done);
      else loader.defaultMeshLoader(path, loadingManager, material, done);
    };
    loader.load(
      spec.urdf,
      (model) => {
        model.position.set(...spec.base.xyz);
        model.quaternion.set(...spec.base.quaternion_xyzw);
        parent.add(model);
        this.model = model;
        this.loaded = true;
      },
      undefined,
      (error) => {
        this.error = `the robot's URDF did not load: ${error}`;
      },
    );
  }

  receive(jointState) {
    this.latest = jointState;
    this.received += 1;
  }

  // Pose the model by the latest joint state, if it is new: joint states arrive faster than some headsets draw.
  update() {
    if (!this.model || this.latest === this.applied) return;
    const { names, positions } = this.latest;
    names.forEach((name, k) => this.model.setJointValue(name, positions[k]));
    this.applied = this.latest;
  }
}

// urdf-loader's mesh callback for an OBJ file: its own materials when its .mtl loads, else the URDF's.
function loadObj(path, loadingManager, material, done) {
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
