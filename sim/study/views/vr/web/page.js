// The VR condition's page: the robot from its URDF, the table and the hand in the headset, moved by the robot's
// joint states at the headset's frame rate; the trial's phase and instructions on a panel in view; the trigger,
// buttons and controllers as the participant's answers (study.js); during a trial, the headset's and the controllers'
// poses as the participant's tracked body (tracking.js, poses.js), after a rest at the session's start that measures
// its jitter (rest.js). It is a client of the endpoint's WebSocket
// transport (connection.js), reached through this page's own server at /ros.
//
// Once its settings have come (by the cookie that keeps the launch's key), the key leaves the page's address
// (address.js).
//
// This module puts the parts together; `page` holds them all, the page's whole state. The tests' probe and the
// frame-time instrument import it, and are served only when the page's server is started for them.
import { forgetKey } from './address.js';
import { browserClockMs } from './connection.js';
import { Controllers } from './controllers.js';
import { FrameLoop } from './frameloop.js';
import { Headset } from './headset.js';
import { Panel } from './panel.js';
import { inputDelay } from './presses.js';
import { Rest } from './rest.js';
import { Robot } from './robot.js';
import { View } from './scene.js';
import { Participant } from './study.js';
import { StudyTopics } from './topics.js';
import { Tracking } from './tracking.js';

async function startPage() {
  const settings = await (await fetch('/settings.json')).json();
  forgetKey(location, history, settings.key_parameter); // the settings came by the cookie: the key is not needed
  const statusLine = document.getElementById('status');
  const view = new View(settings, document.body);
  const robot = new Robot(settings.robot, view.world);
  const panel = new Panel(view.scene, statusLine);
  const controllers = new Controllers(view.renderer.xr, view.scene);
  const tracking = new Tracking(view.renderer.xr, view.world);
  const participant = new Participant(settings.protocol);
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${settings.ros_path}`;
  const statuses = []; // each status as it arrived: {index, phase, test, ros (ROS time then by the clock offset, s)}
  const topics = new StudyTopics(settings, url, {
    onJoints: (jointState) => robot.receive(jointState),
    onStatus: (status) => {
      statuses.push({ index: status.index, phase: status.phase, test: status.test, ros: topics.rosNow() });
      participant.onStatus(status);
    },
  });
  topics.open();

  // the rest at the session's start, when the page tracks a condition (the settings say how long, and its words)
  const restSays = settings.rest;
  const rest = restSays ? new Rest(restSays.seconds, Object.keys(settings.protocol.poses.bodies)) : null;
  const loop = new FrameLoop({ view, robot, panel, controllers, tracking, participant, topics, rest, restSays });
  view.renderer.setAnimationLoop((time, frame) => loop.step(time, frame));
  window.addEventListener('resize', () => view.resize(window.innerWidth, window.innerHeight));

  const enterButton = document.getElementById('enter');
  const triggers = []; // each trigger press: {readAt, stampedAt (ms, performance.now()), inputDelay (s or null)}
  const headset = new Headset(view.renderer.xr, enterButton, statusLine, (readAt) => {
    const now = performance.now(); // first: the press's input delay ends at its stamp
    const delay = inputDelay(now, readAt);
    triggers.push({ readAt, stampedAt: now, inputDelay: delay });
    topics.send(participant.onTrigger(topics.rosNow(browserClockMs(now))), delay);
  });
  await headset.offer();
  return {
    settings,
    view,
    robot,
    panel,
    controllers,
    tracking,
    participant,
    topics,
    loop,
    rest,
    headset,
    triggers,
    statuses,
  };
}

export const page = await startPage();
