// For tests/unit/sim/study/views/test_vr_page_js.py: what the page's codec (sim/study/views/vr/web/rostcp.js) makes of bytes
// Python wrote, and the bytes it writes, as JSON on stdout. Input: JSON on stdin.
import { readFileSync } from 'node:fs';

import {
  command,
  decodeJointState,
  encodeFloat32,
  encodeHeader,
  encodePoseStamped,
  encodeString,
  frame,
  framesIn,
  rosTime,
} from '../../sim/study/views/vr/web/rostcp.js';
import { stopPayload } from '../../sim/study/views/vr/web/presses.js';

const input = JSON.parse(readFileSync(0, 'utf-8'));
const hex = (bytes) => Buffer.from(bytes).toString('hex');
const state = decodeJointState(Buffer.from(input.joint_state, 'hex'));
const frames = framesIn(Buffer.from(input.frames, 'hex'));
console.log(
  JSON.stringify({
    joint_state: {
      stamp: state.stamp,
      names: state.names,
      positions: [...state.positions],
      velocities: [...state.velocities],
    },
    frames: frames.map(([name, payload]) => [name, hex(payload)]),
    header: hex(encodeHeader(input.header.seq, rosTime(input.header.stamp), input.header.frame_id)),
    stop: hex(stopPayload(input.stop.stamp, input.stop.input_delay, input.stop.frame_id)),
    float32: hex(encodeFloat32(input.float32)),
    pose: hex(
      encodePoseStamped(
        input.pose.seq,
        rosTime(input.pose.stamp),
        input.pose.frame_id,
        input.pose.position,
        input.pose.orientation,
      ),
    ),
    string: hex(encodeString(input.string)),
    frame: hex(frame(input.frame[0], Buffer.from(input.frame[1], 'hex'))),
    command: hex(command('__subscribe', { topic: '/study/trial', message_name: 'std_msgs/String' })),
  }),
);
