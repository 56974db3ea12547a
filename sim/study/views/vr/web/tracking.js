// The participant's tracked body in the session (the trial protocol's poses): the headset's pose and each
// controller's grip, read once a frame and taken into the scene's ROS world frame. What is sent of them, and how the
// frame is turned, is poses.js's; this is the WebXR and three.js side.
import { WorldFrame, trackedBodies } from './poses.js';

export class Tracking {
  // xr: three.js's WebXR manager (renderer.xr); world: the scene's group of ROS's world frame (scene.js).
  constructor(xr, world) {
    this.xr = xr;
    this.world = world;
  }

  // In the session's `frame`: [body, {position, orientation}] in the world frame, for each body tracked in it.
  read(frame) {
    const space = this.xr.getReferenceSpace();
    const grips = [];
    for (const source of this.xr.getSession().inputSources) {
      if (source.gripSpace) grips.push([source.handedness, frame.getPose(source.gripSpace, space)]);
    }
    const bodies = trackedBodies(frame.getViewerPose(space), grips);
    if (bodies.length === 0) return [];
    // the world is placed once, at the seat; its matrix is brought up to date here all the same, as the frame's
    // rendering would, so that the poses never depend on whether a frame was drawn before
    this.world.updateWorldMatrix(true, false);
    const toWorld = new WorldFrame(this.world.matrixWorld.elements);
    return bodies.map(([body, pose]) => [body, toWorld.pose(pose.transform)]);
  }
}
