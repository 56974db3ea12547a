// A stop press as it goes to the runner: a std_msgs/Header whose stamp is when (on the runner's clock; 0: when it
// arrives), whose frame_id is the stop source, and whose seq is the press's input delay (from the input's change to
// its stamp) in microseconds, 0 when it was not measured (the trial protocol's table says so, under its inputs).
// Pure: node tests it, and Python reads the same seq (sim.study.run.protocol.input_delay_from_seq).
import { encodeHeader, rosTime } from './rostcp.js';

const MAX_SEQ = 2 ** 32 - 1; // a uint32

// A press's input delay, measured the same way on both pages: s from the first reading that saw the input's change
// (readMs: the button page's Gamepad API timestamp, the browser's poll that saw it; the VR page's trigger event's
// time, the headset's frame that read it) to its stamp (nowMs), both on performance.now()'s clock. Neither page sees
// the press itself: the time from it to that reading is not in the delay. null when the reading's time is unusable
// (0 or none: some browsers and devices do not keep it; after nowMs: not on this clock).
export function inputDelay(nowMs, readMs) {
  if (typeof readMs !== 'number' || !(readMs > 0) || readMs > nowMs) return null;
  return (nowMs - readMs) / 1000;
}
const SEQ_UNIT_S = 1e-6;

// The Header's seq for an input delay (s): whole microseconds, at least 1 (0 says "not measured"); 0 for null or for
// what is no delay (a negative one comes from clocks that disagree, not from the input).
export function inputDelaySeq(seconds) {
  if (seconds === null || !Number.isFinite(seconds) || seconds < 0) return 0;
  return Math.min(Math.max(Math.round(seconds / SEQ_UNIT_S), 1), MAX_SEQ);
}

// The serialized Header of a press: stamp (s of ROS time, 0 when unknown), inputDelay (s, or null), source.
export function stopPayload(stamp, inputDelay, source) {
  return encodeHeader(inputDelaySeq(inputDelay), rosTime(stamp), source);
}
