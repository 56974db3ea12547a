// The page as a client of the endpoint, over its WebSocket transport: one ROS-TCP frame per binary message.
// Like Unity's connector it registers its topics after connecting, sends a keepalive after each quiet second, and
// connects again (and registers again) when the connection drops. `__ping` measures how far ROS time is ahead of
// this browser's clock (clock.js), for the stamps of the participant's presses; after each answer that gave a sample,
// the estimate is announced to the runner (announceClock), which judges the page's stamps by it. When to ping is
// clock.js's (pingDue): quickly until the estimate is settled, one ping in flight at a time.

import { ClockOffset, PING_GIVE_UP_MS, PING_QUICK_MS, pingDue } from './clock.js';
import { KEEPALIVE, command, commandFields, encodeString, frame, framesIn } from './rostcp.js';

const RECONNECT_DELAY_MS = 1000;
const KEEPALIVE_AFTER_MS = 1000;
const PING_TICK_MS = PING_QUICK_MS / 5; // how often whether a ping is due is asked (clock.js's pingDue)

// This browser's clock (ms since the epoch), read at performance.now()'s instant `performanceMs` (now by default):
// the clock of the Gamepad API's timestamps, the trigger events' and the animation frames' times, in fractions of a
// ms (Date.now()'s are whole ms) and never stepped while the page is open. A press's stamp is read at the instant
// its input delay ends, not at a later Date.now() with the page's work between the two.
export function browserClockMs(performanceMs = performance.now()) {
  return performance.timeOrigin + performanceMs;
}

export class RosConnection {
  // url: the WebSocket's URL; onState(text): what the connection is doing, for the page to show.
  constructor(url, onState = () => {}) {
    this.url = url;
    this.onState = onState;
    this.subscriptions = new Map(); // topic -> [type, handler(payload)]
    this.publishers = new Map(); // topic -> [type, latch]
    this.socket = null;
    this.connected = false;
    this.lastSent = 0;
    this.clockMs = browserClockMs; // the browser's clock the ROS clock is measured against (the tests' own in node)
    this.pings = new Map(); // request_time -> when sent (ms, clockMs()): unanswered, not given up on
    this.lastPingMs = null; // when the last ping was sent (clockMs()); null: none on this connection
    this.pingCount = 0;
    this.clock = new ClockOffset();
    this.clockAnnouncement = null; // [topic, source]: where the clock's estimate goes, and the page it names
    this.lagAnnounced = false; // whether the last announcement's applied offset was being taken up (clock.js)
    this.errors = []; // the endpoint's __error and __warn texts, newest last
    this.opened = 0; // times the socket opened: more than once, it was lost and made again
    this.timers = [];
  }

  subscribe(topic, type, handler) {
    this.subscriptions.set(topic, [type, handler]);
    if (this.connected) this._send(command('__subscribe', { topic, message_name: type }));
  }

  // latch: the endpoint's publisher keeps the last message for subscribers that come later (an announcement).
  // queueSize: how many of the topic's messages the endpoint holds for ROS subscribers that fall behind (it drops
  // the oldest beyond them, and says so).
  advertise(topic, type, latch = false, queueSize = 10) {
    this.publishers.set(topic, [type, latch, queueSize]);
    if (this.connected) this._advertise(topic, type, latch, queueSize);
  }

  _advertise(topic, type, latch, queueSize) {
    this._send(command('__publish', { topic, message_name: type, queue_size: queueSize, latch }));
  }

  // Announce the clock offset's estimate (clock.js's report, with `source`: the stop source the page's presses are
  // named by) on `topic` (of `type`, a std_msgs/String: JSON), after each ping answer that gave a sample, and again
  // once a lag it announced is taken up (clockOffset).
  announceClock(topic, type, source) {
    this.advertise(topic, type);
    this.clockAnnouncement = [topic, source];
  }

  // Publish `payload` (a serialized message) on a topic advertised before; false when not connected.
  publish(topic, payload) {
    if (!this.connected) return false;
    this._send(frame(topic, payload));
    return true;
  }

  // Publish messages ([topic, payload] pairs, each on a topic advertised before) in one WebSocket message: the
  // endpoint takes any number of whole frames in one, and one send costs the page less than one each (a frame's
  // poses); false when not connected.
  publishAll(messages) {
    if (!this.connected) return false;
    const frames = messages.map(([topic, payload]) => frame(topic, payload));
    const bytes = new Uint8Array(frames.reduce((length, part) => length + part.length, 0));
    let at = 0;
    for (const part of frames) {
      bytes.set(part, at);
      at += part.length;
    }
    this._send(bytes);
    return true;
  }

  // ROS time minus this browser's clock (s), from the quickest recent ping and slewed (clock.js); null before any
  // answer.
  // A lag announced is announced again once taken up: the runner judges the page by its latest announcement, which
  // would otherwise stand until the next answer (up to 2 s) for a lag gone within a few frames. A busy page reads an
  // answer just after a frame, so one that moves the estimate is announced with all of its move as the lag.
  get clockOffset() {
    return this._offsetAt(this.clockMs());
  }

  _offsetAt(atMs) {
    const offset = this.clock.offsetAt(atMs);
    if (this.lagAnnounced && !this.clock.lagging(atMs)) this._announceClock();
    return offset;
  }

  // ROS time (s) at atMs on this browser's clock (clockMs(); now by default), and the clock offset it was read with
  // (s), or null without a clock offset: a press keeps both, so that its stamp can be placed on this browser's clock
  // (the offset slews between two readings).
  rosReading(atMs = this.clockMs()) {
    const offset = this._offsetAt(atMs);
    return offset === null ? null : { ros: atMs / 1000 + offset, offset };
  }

  // ROS time (s) at atMs (now by default), or null without a clock offset.
  rosNow(atMs = this.clockMs()) {
    const reading = this.rosReading(atMs);
    return reading === null ? null : reading.ros;
  }

  open() {
    this.onState(`connecting to ${this.url}`);
    const socket = new WebSocket(this.url);
    socket.binaryType = 'arraybuffer';
    this.socket = socket;
    socket.onopen = () => {
      this.connected = true;
      this.opened += 1;
      this.onState('connected');
      this._send(KEEPALIVE);
      for (const [topic, [type, latch, queueSize]] of this.publishers) this._advertise(topic, type, latch, queueSize);
      for (const [topic, [type]] of this.subscriptions) {
        this._send(command('__subscribe', { topic, message_name: type }));
      }
      this._ping();
      this.timers = [
        setInterval(() => this._pingIfDue(), PING_TICK_MS),
        setInterval(() => {
          if (Date.now() - this.lastSent >= KEEPALIVE_AFTER_MS) this._send(KEEPALIVE);
        }, KEEPALIVE_AFTER_MS / 2),
      ];
    };
    socket.onmessage = (event) => this._receive(event.data);
    socket.onclose = (event) => {
      this.connected = false;
      this.pings.clear(); // their answers, if any, were lost with the socket
      this.lastPingMs = null;
      this.timers.forEach(clearInterval);
      this.timers = [];
      this.onState(`disconnected (${event.code}${event.reason ? ': ' + event.reason : ''}); connecting again`);
      setTimeout(() => this.open(), RECONNECT_DELAY_MS);
    };
  }

  _send(bytes) {
    if (this.socket && this.socket.readyState === WebSocket.OPEN) {
      this.socket.send(bytes);
      this.lastSent = Date.now();
    }
  }

  _pingIfDue() {
    const now = this.clockMs();
    for (const [requestTime, sentAt] of this.pings) {
      if (now - sentAt >= PING_GIVE_UP_MS) this.pings.delete(requestTime); // lost: its answer is not waited for
    }
    const unansweredSince = this.pings.size ? Math.min(...this.pings.values()) : null;
    if (pingDue(now, this.lastPingMs, unansweredSince, this.clock.settled)) this._ping();
  }

  _announceClock() {
    if (!this.clockAnnouncement) return;
    const [topic, source] = this.clockAnnouncement;
    const now = this.clockMs();
    this.lagAnnounced = this.clock.lagging(now);
    this.publish(topic, encodeString(JSON.stringify({ source, ...this.clock.report(now) })));
  }

  _ping() {
    const sentAt = this.clockMs();
    this.lastPingMs = sentAt;
    this.pingCount += 1;
    const requestTime = `${new Date(sentAt).toISOString()}#${this.pingCount}`;
    this.pings.set(requestTime, sentAt);
    this._send(command('__ping', { request_time: requestTime }));
  }

  _receive(data) {
    for (const [destination, payload] of framesIn(data)) {
      if (destination === '') continue; // keepalive
      if (destination.startsWith('__')) {
        this._system(destination, commandFields(payload));
        continue;
      }
      const subscription = this.subscriptions.get(destination);
      if (subscription) subscription[1](payload);
    }
  }

  _system(name, fields) {
    if (name === '__ping_response') {
      const sentAt = this.pings.get(fields.request_time);
      this.pings.delete(fields.request_time);
      if (sentAt === undefined || typeof fields.ros_time !== 'number') return;
      if (this.clock.add(sentAt, this.clockMs(), fields.ros_time)) this._announceClock();
    } else if (name === '__error' || name === '__warn') {
      this.errors.push(`${name}: ${fields.text}`);
      console.warn(`endpoint ${name}: ${fields.text}`);
    }
  }
}
