// The ROS-TCP protocol's frames, and the few ROS 1 messages the page reads and writes, in plain ROS 1
// serialization (little-endian; a string is its byte length then UTF-8; an array its count then its elements).
// Pure: no DOM and no socket, so node runs it for the tests.

const encoder = new TextEncoder();
const decoder = new TextDecoder('utf-8', { fatal: true });

export class FrameError extends Error {}

// One frame: the destination's length and bytes, then the payload's length and bytes.
export function frame(destination, payload) {
  const name = encoder.encode(destination);
  const out = new Uint8Array(8 + name.length + payload.length);
  const view = new DataView(out.buffer);
  view.setUint32(0, name.length, true);
  out.set(name, 4);
  view.setUint32(4 + name.length, payload.length, true);
  out.set(payload, 8 + name.length);
  return out;
}

// A system command (`__subscribe`, `__ping`, ...): its JSON as the payload.
export function command(name, fields) {
  return frame(name, encoder.encode(JSON.stringify(fields)));
}

export const KEEPALIVE = frame('', new Uint8Array(0));

// The frames of one WebSocket message ([destination, payload] pairs); FrameError when it ends inside a frame.
export function framesIn(message) {
  const bytes = message instanceof Uint8Array ? message : new Uint8Array(message);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const frames = [];
  let at = 0;
  while (at < bytes.length) {
    if (at + 4 > bytes.length) throw new FrameError('a message ends inside a frame (destination length)');
    const nameLength = view.getUint32(at, true);
    if (at + 8 + nameLength > bytes.length) throw new FrameError('a message ends inside a frame (destination)');
    const destination = decoder.decode(bytes.subarray(at + 4, at + 4 + nameLength));
    const payloadLength = view.getUint32(at + 4 + nameLength, true);
    const start = at + 8 + nameLength;
    if (start + payloadLength > bytes.length) throw new FrameError('a message ends inside a frame (payload)');
    frames.push([destination, bytes.subarray(start, start + payloadLength)]);
    at = start + payloadLength;
  }
  return frames;
}

// The JSON of a system command's payload.
export function commandFields(payload) {
  return JSON.parse(decoder.decode(payload));
}

class Writer {
  constructor() {
    this.parts = [];
    this.length = 0;
  }

  _push(size, write) {
    const part = new Uint8Array(size);
    write(new DataView(part.buffer));
    this.parts.push(part);
    this.length += size;
  }

  uint32(value) {
    this._push(4, (view) => view.setUint32(0, value, true));
  }
  float32(value) {
    this._push(4, (view) => view.setFloat32(0, value, true));
  }

  string(text) {
    const bytes = encoder.encode(text);
    this.uint32(bytes.length);
    this.parts.push(bytes);
    this.length += bytes.length;
  }

  bytes() {
    const out = new Uint8Array(this.length);
    let at = 0;
    for (const part of this.parts) {
      out.set(part, at);
      at += part.length;
    }
    return out;
  }
}

class Reader {
  constructor(bytes) {
    this.bytes = bytes;
    this.view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    this.at = 0;
  }

  _take(size) {
    if (this.at + size > this.bytes.length) throw new FrameError('a message is shorter than its type says');
    const at = this.at;
    this.at += size;
    return at;
  }

  uint32() {
    return this.view.getUint32(this._take(4), true);
  }

  string() {
    const length = this.uint32();
    return decoder.decode(this.bytes.subarray(this._take(length), this.at));
  }

  float64Array() {
    const count = this.uint32();
    const values = new Float64Array(count);
    for (let k = 0; k < count; k++) values[k] = this.view.getFloat64(this._take(8), true);
    return values;
  }

  stringArray() {
    const count = this.uint32();
    const values = [];
    for (let k = 0; k < count; k++) values.push(this.string());
    return values;
  }
}

// ROS time {secs, nsecs} of a time in seconds (rounded to the nanosecond).
export function rosTime(seconds) {
  let secs = Math.floor(seconds);
  let nsecs = Math.round((seconds - secs) * 1e9);
  if (nsecs >= 1e9) {
    secs += 1;
    nsecs -= 1e9;
  }
  return { secs, nsecs };
}

// sensor_msgs/JointState: {stamp (s), names, positions, velocities, efforts}.
export function decodeJointState(bytes) {
  const reader = new Reader(bytes);
  reader.uint32(); // seq
  const secs = reader.uint32();
  const nsecs = reader.uint32();
  reader.string(); // frame_id
  const names = reader.stringArray();
  const positions = reader.float64Array();
  const velocities = reader.float64Array();
  const efforts = reader.float64Array();
  if (positions.length !== names.length) {
    throw new FrameError(`a joint state has ${names.length} names but ${positions.length} positions`);
  }
  return { stamp: secs + nsecs * 1e-9, names, positions, velocities, efforts };
}

// std_msgs/Header.
export function encodeHeader(seq, stamp, frameId) {
  const writer = new Writer();
  writer.uint32(seq);
  writer.uint32(stamp.secs);
  writer.uint32(stamp.nsecs);
  writer.string(frameId);
  return writer.bytes();
}

// geometry_msgs/PoseStamped: Header {seq, stamp ({secs, nsecs}), frameId}, then the pose's position [x, y, z] and
// orientation [x, y, z, w], float64 each. Written into one buffer: the page sends three of them every frame.
export function encodePoseStamped(seq, stamp, frameId, position, orientation) {
  if (position.length !== 3 || orientation.length !== 4) {
    throw new RangeError(
      `a pose is 3 coordinates and 4 of a quaternion, not ${position.length} and ${orientation.length}`,
    );
  }
  const name = encoder.encode(frameId);
  const out = new Uint8Array(16 + name.length + 7 * 8);
  const view = new DataView(out.buffer);
  view.setUint32(0, seq, true);
  view.setUint32(4, stamp.secs, true);
  view.setUint32(8, stamp.nsecs, true);
  view.setUint32(12, name.length, true);
  out.set(name, 16);
  let at = 16 + name.length;
  for (const value of [...position, ...orientation]) {
    view.setFloat64(at, value, true);
    at += 8;
  }
  return out;
}

// std_msgs/Float32.
export function encodeFloat32(value) {
  const writer = new Writer();
  writer.float32(value);
  return writer.bytes();
}

// std_msgs/String.
export function encodeString(text) {
  const writer = new Writer();
  writer.string(text);
  return writer.bytes();
}

export function decodeString(bytes) {
  return new Reader(bytes).string();
}

// std_msgs/Empty.
export const EMPTY = new Uint8Array(0);
