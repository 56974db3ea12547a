// The participant's tracked body, as the trial protocol's poses name it: which bodies a frame of the session sends,
// their poses in the scene's ROS world frame, and the frame's stamp on the runner's clock. Pure: no three.js and no
// WebXR, so node runs it for the tests; tracking.js reads the headset's poses and hands them here.

// What tracks each body in WebXR: the viewer (the headset) is the head, a controller's grip its hand.
export const HEAD = 'head';
export const HAND_OF = { left: 'left_hand', right: 'right_hand' }; // by the input source's handedness

// The bodies to send of one frame, as [body, XRPose] pairs: the viewer's pose (or null), and the grips' [handedness,
// pose or null]. A body is sent only when the runtime tracks it in this frame: no pose, or a pose whose position the
// runtime made up (emulatedPosition: a headset that lost its tracking keeps the last position, or a neck model's),
// is a gap in its tracking, and sends nothing. A handedness other than left and right (`none`), or a second source
// of one hand, is no body of the protocol.
export function trackedBodies(viewerPose, grips) {
  const tracked = (pose) => Boolean(pose) && !pose.emulatedPosition;
  const bodies = tracked(viewerPose) ? [[HEAD, viewerPose]] : [];
  const seen = new Set();
  for (const [handedness, pose] of grips) {
    const body = HAND_OF[handedness];
    if (!body || seen.has(body)) continue;
    seen.add(body);
    if (tracked(pose)) bodies.push([body, pose]);
  }
  return bodies;
}

// A frame's time on the runner's clock (s): frameMs is the animation loop's time (ms on performance.now()'s clock,
// which starts at timeOriginMs on the browser's clock, connection.js's browserClockMs); clockOffset is ROS time minus
// the browser's clock (s, connection.js), null before the endpoint has answered a ping: then the frame has no stamp, and null.
export function frameStamp(frameMs, timeOriginMs, clockOffset) {
  if (clockOffset === null) return null;
  return (timeOriginMs + frameMs) / 1000 + clockOffset;
}

// The ROS world frame as the scene places it in the XR reference space: a rigid transform, given as the world's
// 4x4 matrix in that space (column-major, three.js's matrixWorld.elements). pose() takes a pose from the reference
// space into the world: the inverse of that matrix, applied to position and orientation.
export class WorldFrame {
  constructor(m) {
    // the rotation's rows are its inverse's columns; a rigid matrix's rotation has no scale to undo
    this.rotation = [
      [m[0], m[1], m[2]],
      [m[4], m[5], m[6]],
      [m[8], m[9], m[10]],
    ]; // inverse rotation, row by row
    this.origin = [m[12], m[13], m[14]]; // the world's origin in the reference space
    const [x, y, z, w] = quaternionOf(m);
    this.inverseQuaternion = [-x, -y, -z, w];
  }

  // XRRigidTransform-like {position: {x, y, z}, orientation: {x, y, z, w}} in the reference space -> {position:
  // [x, y, z] (m), orientation: [x, y, z, w]} in the world frame.
  pose(transform) {
    const { position: p, orientation: q } = transform;
    const d = [p.x - this.origin[0], p.y - this.origin[1], p.z - this.origin[2]];
    const position = this.rotation.map((row) => row[0] * d[0] + row[1] * d[1] + row[2] * d[2]);
    const orientation = multiply(this.inverseQuaternion, [q.x, q.y, q.z, q.w]);
    return { position, orientation };
  }
}

// Hamilton product a * b of quaternions [x, y, z, w]: b's rotation, then a's.
function multiply([ax, ay, az, aw], [bx, by, bz, bw]) {
  return [
    aw * bx + ax * bw + ay * bz - az * by,
    aw * by - ax * bz + ay * bw + az * bx,
    aw * bz + ax * by - ay * bx + az * bw,
    aw * bw - ax * bx - ay * by - az * bz,
  ];
}

// The unit quaternion [x, y, z, w] of a column-major 4x4 matrix's rotation (Shepperd's method: the largest of the
// four squares is taken first, so that no division is by a number near zero).
function quaternionOf(m) {
  const [m00, m10, m20, m01, m11, m21, m02, m12, m22] = [m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]];
  const trace = m00 + m11 + m22;
  if (trace > 0) {
    const s = 2 * Math.sqrt(trace + 1);
    return [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4];
  }
  if (m00 > m11 && m00 > m22) {
    const s = 2 * Math.sqrt(1 + m00 - m11 - m22);
    return [s / 4, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s];
  }
  if (m11 > m22) {
    const s = 2 * Math.sqrt(1 + m11 - m00 - m22);
    return [(m01 + m10) / s, s / 4, (m12 + m21) / s, (m02 - m20) / s];
  }
  const s = 2 * Math.sqrt(1 + m22 - m00 - m11);
  return [(m02 + m20) / s, (m12 + m21) / s, s / 4, (m10 - m01) / s];
}
