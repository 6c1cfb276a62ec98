// The bite in progress or just finished: what is being eaten, how the fork
// goes about it, where the arm is in its motion, the force on the fork, and
// how it ended. Updated in place from state events and, between them, from
// the progress events (10 a second during the Acquire).

import { h, s, setAttr, setText, show } from './dom.js';
import { OUTCOME_WORDS, PHASES, newtons, phaseIndex } from './format.js';

const SPARK_W = 240;
const SPARK_H = 48;

export function createBitePanel() {
  const heading = h('h2', { id: 'bite-heading' }, 'Bite');
  const what = h('p', { className: 'bite-what' });
  const actionTitle = h('strong', { className: 'action-title' });
  const actionName = h('span', { className: 'action-name' });
  const actionDesc = h('p', { className: 'action-desc' });
  const action = h(
    'div',
    { className: 'bite-action' },
    h('h3', {}, 'How the fork picks it up'),
    h('p', {}, actionTitle, ' ', actionName),
    actionDesc,
  );

  const steps = PHASES.map((phase) =>
    h(
      'li',
      { 'data-phase': phase.id },
      h('span', { className: 'step-mark', 'aria-hidden': 'true' }),
      h('span', { className: 'step-word' }, phase.word),
      h('span', { className: 'step-hint' }, phase.hint),
      h('span', { className: 'visually-hidden step-state' }),
    ),
  );
  const motion = h(
    'div',
    { className: 'bite-motion' },
    h('h3', { id: 'motion-heading' }, 'Motion'),
    h('ol', { className: 'steps', 'aria-labelledby': 'motion-heading' }, steps),
  );

  const forceValue = h('span', { className: 'force-value' });
  const forcePeak = h('span', { className: 'force-peak' });
  const line = s('polyline', { className: 'spark-line', points: '' });
  const spark = s(
    'svg',
    { className: 'spark', viewBox: `0 0 ${SPARK_W} ${SPARK_H}`, preserveAspectRatio: 'none', 'aria-hidden': 'true' },
    s('line', { className: 'spark-base', x1: 0, y1: SPARK_H - 1, x2: SPARK_W, y2: SPARK_H - 1 }),
    line,
  );
  const force = h(
    'div',
    { className: 'bite-force' },
    h('h3', {}, 'Force on the fork'),
    h('p', { className: 'force-now' }, forceValue, ' ', forcePeak),
    spark,
  );

  const outcomeWord = h('p', { className: 'outcome-word' });
  const outcomeText = h('p', { className: 'outcome-text' });
  const outcomeMore = h('p', { className: 'outcome-more' });
  const outcome = h(
    'div',
    { className: 'bite-outcome' },
    h('h3', {}, 'Outcome'),
    outcomeWord,
    outcomeText,
    outcomeMore,
  );

  const root = h(
    'section',
    { className: 'card bite', 'aria-labelledby': 'bite-heading' },
    heading,
    what,
    action,
    motion,
    force,
    outcome,
  );

  // The bite's live data; state events replace it, progress events add to it.
  let live = { number: 0, phase: '', force: NaN, forces: [], outcome: '' };

  function paintMotion() {
    const at = phaseIndex(live.phase);
    const finished = live.outcome && live.outcome !== 'pending';
    steps.forEach((li, i) => {
      const done = i < at || (i === at && PHASES[i].id === 'ACQUIRE_PHASE_DONE');
      const current = i === at;
      li.classList.toggle('done', done);
      li.classList.toggle('current', current);
      li.classList.toggle('halted', current && (live.outcome === 'stopped' || live.outcome === 'error'));
      setAttr(li, 'aria-current', current ? 'step' : null);
      setText(li.querySelector('.step-mark'), done ? '✓' : current && !finished ? '▶' : current ? '■' : '');
      setText(
        li.querySelector('.step-state'),
        done ? ' (done)' : current ? (finished ? ` (${live.outcome} here)` : ' (now)') : '',
      );
    });
  }

  function paintForce() {
    setText(forceValue, live.forces.length || live.force > 0 ? newtons(live.force) : '–');
    const fs = live.forces;
    if (fs.length < 2) {
      setAttr(line, 'points', '');
      setText(forcePeak, '');
      return;
    }
    const tMax = Math.max(fs[fs.length - 1].t, 1e-3);
    // The robot's own peak once the bite is over; the reports' (10 a second)
    // can miss it.
    const peak = live.peak > 0 ? live.peak : fs.reduce((m, p) => Math.max(m, p.f), 0);
    const fMax = Math.max(peak, 5); // keep a calm line calm: at least 5 N tall
    const points = fs
      .map((p) => `${((p.t / tMax) * SPARK_W).toFixed(1)},${(SPARK_H - 2 - (p.f / fMax) * (SPARK_H - 4)).toFixed(1)}`)
      .join(' ');
    setAttr(line, 'points', points);
    setText(forcePeak, `(peak ${newtons(peak)})`);
  }

  /** A progress event (BiteEvent) for the bite on show. */
  function progress(event) {
    if (event.bite !== live.number) {
      if (event.bite < live.number) return; // late report of an earlier bite
      live = { number: event.bite, phase: '', force: NaN, forces: [], outcome: 'pending', peak: 0 };
    }
    if (event.phase && event.phase !== 'ACQUIRE_PHASE_UNSPECIFIED') live.phase = event.phase;
    live.force = Number(event.force_n);
    const t = Number(event.elapsed_s);
    const last = live.forces[live.forces.length - 1];
    if (!last || t > last.t) live.forces.push({ t, f: live.force });
    paintMotion();
    paintForce();
  }

  /** The bite from a MealState (`current`). */
  function update(bite) {
    const number = bite?.number ?? 0;
    show(root, number > 0);
    if (number === 0) return;
    setText(heading, `Bite ${number}`);
    // The plate is numbered afresh when it is looked at again after a bite:
    // the number is shown only while it is the plate's.
    const chosen = bite.robots_choice ? " (the robot's choice)" : '';
    const numbered = bite.outcome === 'pending' || !bite.food;
    const item = `Item ${bite.item_index + 1}${chosen}`;
    setText(what, !bite.food ? item : numbered ? `${item}: ${bite.food}` : `${bite.food}${chosen}`);

    const act = bite.action || {};
    show(action, Boolean(act.name || act.title));
    setText(actionTitle, act.title || act.name || '');
    setText(actionName, act.title && act.name ? `(${act.name})` : '');
    setText(actionDesc, act.description || '');

    // A state event is complete: it replaces what progress events added.
    const forces = (bite.forces || []).map((p) => ({ t: Number(p.t), f: Number(p.f) }));
    const fresher = live.number === number && live.forces.length > forces.length && bite.outcome === 'pending';
    live = {
      number,
      phase: fresher ? live.phase : bite.phase,
      force: fresher ? live.force : Number(bite.force_n),
      forces: fresher ? live.forces : forces,
      outcome: bite.outcome,
      peak: bite.outcome && bite.outcome !== 'pending' ? Number(bite.peak_force_n) || 0 : 0,
    };
    paintMotion();
    paintForce();

    root.dataset.outcome = bite.outcome || '';
    outcomeWord.className = `outcome-word outcome-${bite.outcome || 'pending'}`;
    let word = OUTCOME_WORDS[bite.outcome] ?? bite.outcome ?? '';
    if (bite.outcome === 'pending' && bite.question) word = 'Waiting for your answer';
    if (bite.answer) word += ` (your answer: ${bite.answer})`;
    setText(outcomeWord, word);
    setText(outcomeText, bite.error && !bite.text?.includes(bite.error) ? `${bite.text} ${bite.error}` : bite.text);
    const more = [];
    if (bite.haptic?.label && bite.haptic.probabilities?.length) {
      more.push(`Felt ${bite.haptic.label} (${Math.round(bite.haptic.probability * 100)}% sure)`);
    } else if (bite.haptic?.label) {
      more.push(`Felt ${bite.haptic.label}`);
    }
    if (bite.force_limit_reached) {
      const limit = Number(bite.action?.max_force_n) > 0 ? `${Math.round(Number(bite.action.max_force_n))} N ` : '';
      more.push(`The fork stopped pushing at its ${limit}limit, so the trace is cut short`);
    }
    if (bite.learned && bite.learned !== 'pending') more.push(`Learning: ${bite.learned}`);
    setText(outcomeMore, more.join('. '));
  }

  return { root, update, progress };
}
