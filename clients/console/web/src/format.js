// Words and numbers as people read them.

/** The Acquire phases in the order the arm runs them (robot.proto). */
export const PHASES = [
  { id: 'ACQUIRE_PHASE_APPROACH', word: 'Approach', hint: 'moving above the food' },
  { id: 'ACQUIRE_PHASE_ORIENT', word: 'Orient', hint: 'turning the fork' },
  { id: 'ACQUIRE_PHASE_DESCEND', word: 'Descend', hint: 'pushing the fork into the food' },
  { id: 'ACQUIRE_PHASE_EXTRACT', word: 'Extract', hint: 'lifting the food' },
  { id: 'ACQUIRE_PHASE_DONE', word: 'Done', hint: 'the arm is back' },
];

/** Index into PHASES, or -1 (UNSPECIFIED: the Acquire has not begun). */
export function phaseIndex(phase) {
  return PHASES.findIndex((p) => p.id === phase);
}

export function phaseWord(phase) {
  return PHASES[phaseIndex(phase)]?.word ?? '';
}

/** "1 attempt", "2 attempts". */
export function count(n, singular, plural = `${singular}s`) {
  return `${n} ${Number(n) === 1 ? singular : plural}`;
}

/** A person's learner (UserConfig.learner, the API's name) as people read it. */
export const LEARNER_WORDS = {
  LEARNER_POSTHOC: 'post hoc LinUCB',
  LEARNER_POLINUCB: 'poLinUCB',
  LEARNER_CONTEXT_ONLY: 'vision only (context-only LinUCB)',
};

export function learnerWord(learner) {
  return LEARNER_WORDS[learner] ?? `an unknown learner (${learner || 'unset'})`;
}

/** Three significant digits, without a "-0": 0.904, -0.0442, -0.000245, 0. */
export function threeDigits(x) {
  if (!Number.isFinite(x)) return '–';
  const rounded = Number(x.toPrecision(3));
  return rounded === 0 ? '0' : String(rounded);
}

export function newtons(f) {
  return Number.isFinite(f) ? `${f.toFixed(1)} N` : '–';
}

/** 64-bit integers arrive as strings (protobuf JSON); small ones fit a Number. */
export function int(value) {
  const n = Number(value ?? 0);
  return Number.isFinite(n) ? n : 0;
}

const timeFormat = new Intl.DateTimeFormat(undefined, {
  year: 'numeric',
  month: 'short',
  day: 'numeric',
  hour: '2-digit',
  minute: '2-digit',
  second: '2-digit',
});

/** An RFC 3339 timestamp (protobuf JSON) in local time; unset ones as a dash. */
export function when(timestamp) {
  if (!timestamp) return '–';
  const date = new Date(timestamp);
  if (Number.isNaN(date.getTime()) || date.getTime() <= 0) return '–';
  return timeFormat.format(date);
}

/**
 * Where an item lies in the picture, in thirds: "top left", "centre",
 * "bottom", "right"... Used in each item's accessible name.
 */
export function placeOf(item, width, height) {
  const u = item.center_px?.u ?? item.bbox.x + item.bbox.width / 2;
  const v = item.center_px?.v ?? item.bbox.y + item.bbox.height / 2;
  const col = ['left', 'centre', 'right'][Math.min(2, Math.max(0, Math.floor((3 * u) / width)))];
  const row = ['top', 'middle', 'bottom'][Math.min(2, Math.max(0, Math.floor((3 * v) / height)))];
  if (row === 'middle') return col;
  if (col === 'centre') return row;
  return `${row} ${col}`;
}

/** "Item 3, at top left" (items are numbered from 1 for people). */
export function itemName(index, item, width, height) {
  const place = item && width > 0 && height > 0 ? `, at ${placeOf(item, width, height)}` : '';
  return `Item ${index + 1}${place}`;
}

export const OUTCOME_WORDS = {
  pending: 'In progress',
  success: 'Success: the food came up',
  failure: 'Failure: the food did not come up',
  stopped: 'Stopped',
  error: 'Error',
};
