// The page's side of the study over ROS, through the endpoint's client (connection.js): the robot's joint states and
// the trial's status in, the participant's answers and tracked body (poses.js) out, on the topics of the settings.
import { RosConnection } from './connection.js';
import { stopPayload } from './presses.js';
import {
  EMPTY,
  decodeJointState,
  decodeString,
  encodeFloat32,
  encodePoseStamped,
  encodeString,
  rosTime,
} from './rostcp.js';

export class StudyTopics {
  // url: the endpoint's WebSocket (through this page's server); onJoints(jointState), onStatus(trial status object).
  constructor(settings, url, { onJoints, onStatus }) {
    this.settings = settings;
    this.state = 'connecting'; // what the connection is doing, for the panel
    this.connection = new RosConnection(url, (state) => {
      this.state = state;
    });
    this.sent = []; // the answers published: [input, value], oldest first
    const topics = settings.topics;
    this.connection.subscribe(topics.joint_states[0], topics.joint_states[1], (payload) => {
      onJoints(decodeJointState(payload));
    });
    this.connection.subscribe(topics.trial[0], topics.trial[1], (payload) => {
      onStatus(JSON.parse(decodeString(payload)));
    });
    for (const name of Object.keys(settings.protocol.inputs)) this.connection.advertise(...topics[name]);
    this.poseFrame = settings.protocol.poses.frame_id;
    this.posesSent = {}; // body -> poses published, which is the next one's seq
    for (const body of Object.keys(settings.protocol.poses.bodies)) {
      this.connection.advertise(...topics[body]);
      this.posesSent[body] = 0;
    }
  }

  open() {
    this.connection.open();
  }

  get connected() {
    return this.connection.connected;
  }

  // Now in ROS time (s), or null before the endpoint has answered a ping.
  rosNow() {
    return this.connection.rosNow();
  }

  // ROS time minus this browser's clock (s), or null before the endpoint has answered a ping.
  get clockOffset() {
    return this.connection.clockOffset;
  }

  // Publish the bodies' poses ([body, {position, orientation}] in the world frame, poses.js) of one frame, stamped
  // with its time (s of ROS time), each on its body's topic, in one send; false when not connected.
  sendPoses(stamp, bodies) {
    if (bodies.length === 0) return true;
    const time = rosTime(stamp);
    const messages = bodies.map(([body, pose]) => [
      this.settings.topics[body][0],
      encodePoseStamped(this.posesSent[body], time, this.poseFrame, pose.position, pose.orientation),
    ]);
    if (!this.connection.publishAll(messages)) return false;
    for (const [body] of bodies) this.posesSent[body] += 1; // the next one's seq
    return true;
  }

  // Publish a participant's answer ([input, value], study.js), if any, on its input's topic; a stop with its input
  // delay (s, or null when not measured), which goes in the Header's seq (presses.js).
  send(action, inputDelay = null) {
    if (!action) return;
    const [what, value] = action;
    const payload = {
      go: () => EMPTY,
      stop: () => stopPayload(value, inputDelay, this.settings.stop_source),
      distance: () => encodeFloat32(value),
      preference: () => encodeString(value),
      answer: () => encodeString(JSON.stringify(value)), // {administration, item, answer}, as the runner reads it
    }[what]();
    if (this.connection.publish(this.settings.topics[what][0], payload)) this.sent.push([what, value]);
  }
}
