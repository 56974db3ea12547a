// The tests' view into the page (window.vrPage): served and loaded only with the page server's --emulate-headset,
// never in a participant's headset.
import { page } from './page.js';

window.vrPage = {
  page, // every part, for what the tests drive (the session, the connection's clock)

  session() {
    return page.view.renderer.xr.getSession();
  },

  // What the tests wait on and check, as plain data.
  state() {
    const status = page.participant.status;
    return {
      connected: page.topics.connected,
      robot: page.robot.loaded,
      meshes: page.robot.meshesLoaded,
      jointStates: page.robot.received,
      inSession: page.headset.inSession,
      enterable: !page.headset.button.disabled,
      frames: page.loop.frames,
      inTrial: page.participant.inTrial, // the page sends the tracked body in its session's frames
      poseFrames: page.loop.poseFrames, // the session's frames that sent the tracked body
      posesSent: { ...page.topics.posesSent }, // by body
      // the rest at the session's start: over or not, each body's positions kept then (world frame) and the
      // announcement as it stands
      rest: page.rest ? { done: page.rest.done, samples: page.rest.samples } : null,
      announcement: page.topics.announcement,
      triggers: page.headset.triggers,
      triggerPresses: page.triggers, // each: when it was read and stamped (ms), its input delay (s)
      statuses: page.statuses, // each status as it arrived, with the page's ROS time then
      actions: page.topics.sent,
      endpointSaid: [...page.topics.connection.errors], // its __error and __warn texts (dropped messages among them)
      opened: page.topics.connection.opened, // the connection's opens: more than one, it was lost meanwhile
      index: status ? status.index : null,
      phase: status ? status.phase : null,
      item: status && status.item ? status.item : null, // a questionnaire's
      panel: page.panel.text, // the panel's title and lines
      error: page.robot.error || page.headset.error,
    };
  },
};
