// The page's study rules (sim/study/views/vr/web/study.js) and ROS-TCP frames (rostcp.js), run by node's test runner
// (tests/unit/sim/study/views/test_vr_page_js.py runs this file and cross-checks the bytes against Python).
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import {
  FrameError,
  KEEPALIVE,
  command,
  commandFields,
  frame,
  framesIn,
  rosTime,
} from '../../sim/study/views/vr/web/rostcp.js';
import {
  ControllerEdges,
  HeldUntilRead,
  PRIMARY_BUTTON,
  Participant,
  answerLabel,
  firstAnswer,
  wrapped,
} from '../../sim/study/views/vr/web/study.js';

// the trial protocol's table, as the page gets it in its settings
const PROTOCOL = JSON.parse(readFileSync(new URL('../../sim/study/run/protocol.json', import.meta.url)));

function status(phase, extra = {}) {
  return {
    participant: 3,
    index: 2,
    total: 4,
    phase,
    condition: 'vr',
    test: 2,
    path: 'straight',
    standoff: 0,
    peak_speed: 0.3,
    speed_set: 'fast',
    group: 1,
    motion_start: null,
    group_paths: [],
    ...extra,
  };
}

test('the trigger stops only while the robot moves, stamped on the runner clock or zero', () => {
  const participant = new Participant(PROTOCOL);
  participant.onStatus(status('ready'));
  assert.equal(participant.onTrigger(12.0), null);
  participant.onStatus(status('moving', { motion_start: 10.0 }));
  assert.deepEqual(participant.onTrigger(12.5), ['stop', 12.5]);
  assert.deepEqual(participant.onTrigger(null), ['stop', 0]); // no clock offset yet
  assert.deepEqual(participant.onTrigger(1.79e9), ['stop', 0]); // the wall clock, not the runner's /clock
});

test('A says go once per ready phase', () => {
  const participant = new Participant(PROTOCOL);
  participant.onStatus(status('ready'));
  assert.deepEqual(participant.onConfirm(null), ['go']);
  assert.equal(participant.onConfirm(null), null);
  participant.onStatus(status('ready', { index: 3 }));
  assert.deepEqual(participant.onConfirm(null), ['go']);
});

test("the distance is the controllers' when both are tracked and within reach", () => {
  const participant = new Participant(PROTOCOL);
  participant.onStatus(status('distance', { test: 1 }));
  assert.equal(participant.onConfirm(null), null);
  assert.match(participant.instructions()[1][0], /distance between the robot and the hand/);
  assert.match(participant.instructions()[1].at(-1), /both controllers/);
  assert.equal(participant.onConfirm(2.5), null); // beyond the table's limit
  assert.match(participant.notice, /within 2 m/);
  assert.deepEqual(participant.onConfirm(0.12), ['distance', 0.12]);
  assert.equal(participant.onConfirm(0.2), null); // answered once
  assert.deepEqual(participant.instructions()[1], ['Thank you.']);
});

// an SSQ item's status, as the runner's item_status makes it
const SYMPTOM = {
  test: 0,
  administration: 'ssq_before_vr',
  scale_low: 0,
  scale_high: 3,
  scale_labels: ['none', 'slight', 'moderate', 'severe'],
};

test("a questionnaire's item starts unanswered, and a confirm without a choice is refused, visibly", () => {
  const participant = new Participant(PROTOCOL);
  participant.onStatus(status('questionnaire', { ...SYMPTOM, item: 'nausea', item_text: 'Nausea', item_number: 8 }));
  const [title, lines] = participant.instructions();
  assert.equal(title, 'Question 8 of {item_count}'); // a field the status lacks stays as written
  assert.deepEqual(lines.slice(0, 2), ['Nausea', '< ?: no answer yet >']);
  assert.equal(participant.onConfirm(null), null); // no default answer: nothing is sent
  assert.equal(participant.answered, false);
  assert.match(participant.instructions()[1].at(-1), /Choose an answer with the thumbstick first/);
  participant.onChoose(-1); // from no choice: in from the right end of 0..3, its highest point
  assert.equal(participant.instructions()[1][1], '< 3: severe >');
  assert.doesNotMatch(participant.instructions()[1].at(-1), /Choose an answer/); // the notice goes once chosen
  participant.onChoose(-1);
  assert.deepEqual(participant.onConfirm(null), [
    'answer',
    { administration: 'ssq_before_vr', item: 'nausea', answer: 2 },
  ]);
  assert.equal(participant.onConfirm(null), null); // answered once
  assert.deepEqual(participant.instructions()[1], ['Thank you.']);
  const next = { ...SYMPTOM, item: 'vertigo', item_text: 'Vertigo', item_number: 9, item_count: 16 };
  participant.onStatus(status('questionnaire', next));
  assert.equal(participant.answered, false);
  assert.equal(participant.answer, null); // each item afresh: the last item's answer is not offered
  assert.deepEqual(participant.instructions(), [
    'Question 9 of 16',
    ['Vertigo', '< ?: no answer yet >', 'Thumbstick to choose an answer, A (or X) to confirm it.'],
  ]);
  // the same item of another administration at the same place is a new question, not one said again
  participant.onChoose(+1);
  participant.onConfirm(null);
  participant.onStatus(status('questionnaire', { ...next, administration: 'ssq_after_vr' }));
  assert.equal(participant.answer, null);
  assert.equal(participant.notice, '');
});

// the fields by which an answer names its item
function pick({ administration, item }) {
  return { administration, item };
}

test("the thumbstick walks an item's scale from the end it enters by, one point a push, and stops at its ends", () => {
  const participant = new Participant(PROTOCOL);
  const safety = {
    administration: 'perceived_safety_after_vr',
    item: 'perceived_safety',
    scale_low: 1,
    scale_high: 7,
    scale_labels: ['not at all safe', '', '', '', '', '', 'completely safe'],
  };
  participant.onStatus(status('questionnaire', safety));
  assert.equal(participant.answer, null);
  participant.onChoose(+1); // the first push right enters from the left: the lowest point
  assert.equal(participant.answer, 1);
  assert.equal(participant.instructions()[1][1], '< 1: not at all safe >');
  participant.onChoose(+1);
  assert.equal(participant.instructions()[1][1], '< 2: between not at all safe and completely safe >');
  for (let push = 0; push < 8; push += 1) participant.onChoose(+1);
  assert.equal(participant.instructions()[1][1], '< 7: completely safe >');
  participant.onChoose(-1);
  assert.deepEqual(participant.onConfirm(null), ['answer', { ...pick(safety), answer: 6 }]);
  participant.onChoose(-1); // answered: the thumbstick changes nothing
  assert.equal(participant.answer, 6);
  for (let push = 0; push < 9; push += 1) participant.onChoose(-1);
  assert.equal(participant.answer, 6);
});

test('the first push favours no point: each direction enters at its own end, never the middle', () => {
  for (const [low, high] of [
    [0, 3],
    [0, 6],
    [1, 5],
    [1, 7],
  ]) {
    const scale = { scale_low: low, scale_high: high };
    assert.equal(firstAnswer(scale, +1), low);
    assert.equal(firstAnswer(scale, -1), high);
  }
  // pushes in one direction walk the whole scale from the end they entered by, the two directions mirrored
  const participant = new Participant(PROTOCOL);
  const walked = (direction, pushes) => {
    participant.onStatus(status('questionnaire', { ...SYMPTOM, item: `walk ${direction} ${pushes}` }));
    for (let push = 0; push < pushes; push += 1) participant.onChoose(direction);
    return participant.answer;
  };
  assert.deepEqual(
    [1, 2, 3, 4, 5].map((pushes) => walked(+1, pushes)),
    [0, 1, 2, 3, 3],
  );
  assert.deepEqual(
    [1, 2, 3, 4, 5].map((pushes) => walked(-1, pushes)),
    [3, 2, 1, 0, 0],
  );
});

test('the labels of points between labelled ones', () => {
  const aware = {
    scale_low: 0,
    scale_labels: ['extremely aware', '', '', 'moderately aware', '', '', 'not aware at all'],
  };
  assert.equal(answerLabel(aware, 3), 'moderately aware');
  assert.equal(answerLabel(aware, 1), 'between extremely aware and moderately aware');
  assert.equal(answerLabel(aware, 5), 'between moderately aware and not aware at all');
  assert.equal(answerLabel({ scale_low: 1, scale_labels: ['', '', ''] }, 2), '');
});

test('an item said again after its answer was refused is asked again, from the point shown', () => {
  const participant = new Participant(PROTOCOL);
  const nausea = status('questionnaire', { ...SYMPTOM, item: 'nausea', item_text: 'Nausea' });
  participant.onStatus(nausea);
  participant.onChoose(+1);
  participant.onChoose(+1);
  assert.deepEqual(participant.onConfirm(null)[1].answer, 1);
  participant.onStatus({ ...nausea }); // the runner refused it and says the item again
  assert.equal(participant.answered, false);
  assert.equal(participant.instructions()[1][1], '< 1: slight >');
  assert.match(participant.instructions()[1].at(-1), /not taken/);
  assert.deepEqual(participant.onConfirm(null)[1].answer, 1);
  assert.equal(participant.notice, '');
  // a preference's status said again is not a question asked again
  participant.onStatus(status('preference', { group_paths: ['straight'] }));
  assert.deepEqual(participant.onConfirm(null), ['preference', 'straight']);
  participant.onStatus(status('preference', { group_paths: ['straight'] }));
  assert.equal(participant.onConfirm(null), null);
});

test("the thumbstick walks the group's paths and A chooses the one shown", () => {
  const participant = new Participant(PROTOCOL);
  participant.onStatus(status('preference', { group_paths: ['straight', 'vertical', 'lateral_arc'] }));
  participant.onChoose(-1);
  assert.match(participant.instructions()[1][1], /3: lateral_arc/);
  participant.onChoose(+1);
  participant.onChoose(+1);
  assert.deepEqual(participant.onConfirm(null), ['preference', 'vertical']);
});

test('every phase of the table has its words on the panel', () => {
  const participant = new Participant(PROTOCOL);
  for (const phase of PROTOCOL.phases) {
    participant.onStatus(status(phase.name, { index: 5, group_paths: ['straight'], ...SYMPTOM }));
    const [title, lines] = participant.instructions();
    assert.equal(title, phase.panel.title || 'Trial 5 of 4');
    const filled = { '{choice}': '1', '{path}': 'straight', '{answer}': '?', '{label}': 'no answer yet' };
    assert.deepEqual(
      lines,
      phase.panel.lines.map((line) => line.replace(/\{\w+\}/g, (key) => filled[key] || key)),
    );
  }
});

test('button and thumbstick edges', () => {
  const edges = new ControllerEdges();
  const pressed = [false, false, false, false, true];
  assert.deepEqual(edges.update(pressed, [0, 0, 0, 0]), { confirm: true, choose: 0 });
  assert.deepEqual(edges.update(pressed, [0, 0, 0.9, 0]), { confirm: false, choose: 1 });
  assert.deepEqual(edges.update([], [0, 0, 0.95, 0]), { confirm: false, choose: 0 }); // still pushed
  assert.deepEqual(edges.update([], [0, 0, 0.1, 0]), { confirm: false, choose: 0 });
  assert.deepEqual(edges.update([], [0, 0, -0.7, 0]), { confirm: false, choose: -1 });
});

// A runtime that reads a controller once a frame, as WebXR does (and IWER: a button's latest value, applied at the
// next frame's start): `changes` are [ms, pressed] of A, `frames` the frames' times (ms). The page's confirms.
function confirmsOver(changes, frames, held) {
  const edges = new ControllerEdges();
  const button = held ? new HeldUntilRead(false) : null;
  let current = false;
  let confirms = 0;
  let next = 0; // the first change not yet made
  for (const at of frames) {
    for (; next < changes.length && changes[next][0] <= at; next += 1) {
      const down = changes[next][1];
      if (button) button.set(down);
      else current = down;
    }
    const pressed = button ? button.read() : current;
    const buttons = [];
    buttons[PRIMARY_BUTTON] = pressed;
    if (edges.update(buttons, [0, 0, 0, 0]).confirm) confirms += 1;
  }
  return confirms;
}

test('one press counts once, however slow the frames: held until a frame has read it', () => {
  // a person's press of 150 ms, at 72 Hz: several frames see it, the first one counts
  const quick = Array.from({ length: 40 }, (_, k) => k * 13.9);
  assert.equal(
    confirmsOver(
      [
        [100, true],
        [250, false],
      ],
      quick,
      false,
    ),
    1,
  );
  // the same press between two frames of software rendering (400 ms apart) was lost: the miss
  const slow = [0, 400, 800, 1200];
  assert.equal(
    confirmsOver(
      [
        [450, true],
        [600, false],
      ],
      slow,
      false,
    ),
    0,
  );
  // held until read, the next frame sees it, once, and the one after sees it released
  assert.equal(
    confirmsOver(
      [
        [450, true],
        [600, false],
      ],
      slow,
      true,
    ),
    1,
  );
  assert.equal(
    confirmsOver(
      [
        [100, true],
        [250, false],
      ],
      quick,
      true,
    ),
    1,
  );
  // two presses between the same two frames are one press to a runtime that reads once a frame
  assert.equal(
    confirmsOver(
      [
        [450, true],
        [500, false],
        [550, true],
        [600, false],
      ],
      slow,
      true,
    ),
    1,
  );
  // a press still held at the next frame, and released later, is one press too
  assert.equal(
    confirmsOver(
      [
        [450, true],
        [1000, false],
      ],
      slow,
      true,
    ),
    1,
  );
});

test('a held value: a change away from rest stays until read; a change while read applies at once', () => {
  const stick = new HeldUntilRead();
  stick.set(0.9);
  stick.set(0); // released before any reading
  assert.equal(stick.read(), 0.9);
  assert.equal(stick.read(), 0);
  stick.set(-0.8);
  assert.equal(stick.read(), -0.8);
  stick.set(0); // already read: back to rest at once
  assert.equal(stick.read(), 0);
  stick.set(0.7);
  stick.set(0.95); // another push before a reading: the latest
  assert.equal(stick.read(), 0.95);
});

// the panel's lines measured by characters
const measure = (text) => text.length;

test('panel lines: long ones break at spaces to fit; short and empty ones stay as they are', () => {
  assert.deepEqual(wrapped(['I felt present in the virtual space.', '', 'Thank you.'], 16, measure), [
    'I felt present',
    'in the virtual',
    'space.',
    '',
    'Thank you.',
  ]);
  assert.deepEqual(wrapped(['< 3: slight >'], 13, measure), ['< 3: slight >']); // exactly the width
  assert.deepEqual(wrapped(['a indistinguishable b'], 8, measure), ['a', 'indistinguishable', 'b']);
});

test('frames: several in one message, and a message that ends inside one', () => {
  const message = new Uint8Array([
    ...frame('/t', new Uint8Array([1, 2, 3])),
    ...KEEPALIVE,
    ...command('__ping', { a: 1 }),
  ]);
  const frames = framesIn(message);
  assert.deepEqual(
    frames.map(([name]) => name),
    ['/t', '', '__ping'],
  );
  assert.deepEqual([...frames[0][1]], [1, 2, 3]);
  assert.deepEqual(commandFields(frames[2][1]), { a: 1 });
  for (const cut of [2, 5, 9, message.length - 1]) assert.throws(() => framesIn(message.subarray(0, cut)), FrameError);
});

test('ROS time to the nanosecond', () => {
  assert.deepEqual(rosTime(1.16), { secs: 1, nsecs: 160000000 });
  assert.deepEqual(rosTime(2.9999999999), { secs: 3, nsecs: 0 });
});
