// The table view, played through a simulated meal on a real bitewise-console:
// choose someone new and start by keyboard alone, bite an item by keyboard,
// follow the bite down the page while the plate is drawn again (the page
// stays put), tap an item, reload mid-bite, answer the operator's question
// (when the console asks, BITEWISE_CONSOLE_OPERATOR=1), a stream gone
// silent (the page says the connection is lost and takes no bite), STOP
// during DESCEND and its line cleared by the next bite, and the meal's
// summary. axe-core checks every state, and each state is
// screenshotted at 360x740 and 1024x768.

import assert from 'node:assert/strict';
import { after, before, describe, it } from 'node:test';
import {
  BASE,
  OPERATOR,
  SKIP,
  api,
  biteJudged,
  checkAxe,
  endAnyMeal,
  launchBrowser,
  mealState,
  openPage,
  press,
  readyForBite,
  screenshot,
  screenshotDirectory,
  tabTo,
  waitForMeal,
  waitIn,
} from './helpers.mjs';

const PHASE_ORDER = ['APPROACH', 'ORIENT', 'DESCEND', 'EXTRACT', 'DONE'].map((p) => `ACQUIRE_PHASE_${p}`);

describe('table view', { skip: SKIP }, () => {
  let chromium;
  let page;
  let record;
  const person = `web-table-${Date.now().toString(36)}`;

  /** Records, in the page, every step that becomes aria-current. */
  const watchPhases = () =>
    page.evaluate(() => {
      window.__phasesSeen = [];
      const steps = document.querySelector('.bite .steps');
      const note = () => {
        const now = steps.querySelector('li[aria-current="step"]')?.dataset.phase;
        const seen = window.__phasesSeen;
        if (now && seen[seen.length - 1] !== now) seen.push(now);
      };
      new MutationObserver(note).observe(steps, { subtree: true, attributes: true, attributeFilter: ['aria-current'] });
    });

  /** Waits until the page's plate takes a tap (the console is ready for a bite). */
  const waitForPlate = async () => {
    await waitForMeal(readyForBite, 60000, 'the plate to be ready');
    await waitIn(
      page,
      () =>
        document.querySelector('#robots-choice:not([aria-disabled])') &&
        document.querySelector('.plate-overlay .item[aria-disabled="false"]'),
    );
  };

  const currentPhase = (phase) =>
    waitIn(page, (p) => document.querySelector(`.bite li[data-phase="${p}"][aria-current="step"]`), phase);

  /** Waits for the verdict (or the question) of bite `number` on the page. */
  const waitForVerdict = async (number) => {
    const state = await waitForMeal(biteJudged(number), 60000, `bite ${number}'s verdict`);
    await waitIn(
      page,
      (asked) =>
        asked
          ? !document.querySelector('.question').hidden
          : !['', 'pending'].includes(document.querySelector('.bite').dataset.outcome),
      Boolean(state.current.question),
    );
    return state;
  };

  const answerIfAsked = async (state, yes) => {
    if (!state.current.question) return;
    await press(page, yes ? '.question .yes' : '.question .no');
    await waitForMeal((s) => s.current.answer === (yes ? 'yes' : 'no'), 10000, 'the answer');
  };

  before(async () => {
    await endAnyMeal();
    chromium = await launchBrowser();
    ({ page, record } = await openPage(chromium.browser));
    console.log(`screenshots in ${await screenshotDirectory()}`);
  });

  after(async () => {
    await chromium?.close();
    // Leave the console free for whoever comes next.
    if (BASE) await endAnyMeal().catch(() => {});
  });

  it('shows STOP before any data has loaded', async () => {
    await page.goto(`${BASE}/#/table`, { waitUntil: 'domcontentloaded' });
    const stop = await page.$eval('#stop-button', (b) => {
      const box = b.getBoundingClientRect();
      return { text: b.textContent.trim(), visible: box.width > 0 && box.height > 0 && box.bottom <= innerHeight };
    });
    assert.deepEqual(stop, { text: 'STOP', visible: true });
  });

  it('starts a meal for someone new by keyboard alone', async () => {
    await waitIn(page, () => document.querySelector('.start') && !document.querySelector('.start').hidden);
    await waitIn(page, () => !document.querySelector('.people-status')?.textContent.startsWith('Loading'));
    await screenshot(page, 'table-01-start', '.start');
    await checkAxe(page, 'the start form');

    await page.evaluate(() => document.activeElement?.blur());
    await tabTo(page, '#new-person-name');
    await page.keyboard.type(person);
    await page.keyboard.press('Enter');
    const chosen = await page.$eval('.people input[name="person"]:checked', (r) => r.value);
    assert.equal(chosen, person);
    await tabTo(page, '#start-meal');
    await page.keyboard.press('Enter');

    const state = await waitForMeal(readyForBite, 60000, 'the first look at the plate');
    assert.equal(state.user_id, person);
    await waitIn(page, () => document.querySelectorAll('.plate-overlay .item').length > 0);
    await waitIn(page, () => document.querySelector('.plate-img') && !document.querySelector('.plate-img').hidden);
    const names = await page.$$eval('.plate-overlay .item', (items) => items.map((i) => i.getAttribute('aria-label')));
    assert.equal(names.length, state.items.length);
    names.forEach((name, i) =>
      assert.match(name, new RegExp(`^Item ${i + 1}, at (top |bottom )?(left|centre|right)?`), `item ${i + 1}'s name`),
    );
    await screenshot(page, 'table-02-plate', '.plate-card');
    await checkAxe(page, 'the plate');
  });

  it('bites an item chosen by keyboard and shows its phases, action and force', async () => {
    await waitForPlate();
    await watchPhases();
    await page.evaluate(() => document.activeElement?.blur());
    await tabTo(page, '.plate-overlay .item');
    const index = await page.evaluate(() => Number(document.activeElement.dataset.itemIndex));
    await page.keyboard.press('Enter');

    await currentPhase('ACQUIRE_PHASE_DESCEND');
    let state = await mealState();
    assert.equal(state.current.number, 1);
    assert.equal(state.current.item_index, index);
    assert.equal(state.current.robots_choice, false);
    const shown = await page.evaluate(() => ({
      heading: document.querySelector('#bite-heading').textContent,
      title: document.querySelector('.action-title').textContent,
      description: document.querySelector('.action-desc').textContent,
    }));
    assert.equal(shown.heading, 'Bite 1');
    assert.equal(shown.title, state.current.action.title);
    assert.equal(shown.description, state.current.action.description);
    assert.ok(shown.description.length > 0, 'the action has a plain description');
    await screenshot(page, 'table-03-biting', '.bite');
    await checkAxe(page, 'a bite in DESCEND');

    // The person scrolls down to follow the bite; the keyboard's focus stays
    // on the item, now above the screen. When the plate is drawn again (the
    // bite's end, the next look), the focus comes back to the item without
    // pulling the page up to it.
    const where = () =>
      page.evaluate(() => ({
        bite: document.querySelector('.bite').getBoundingClientRect().top,
        item: document.activeElement.closest('.plate-overlay .item')?.getBoundingClientRect().bottom ?? null,
        y: scrollY,
      }));
    await page.evaluate(() => document.querySelector('.bite').scrollIntoView({ block: 'start' }));
    const before = await where();
    assert.ok(before.item !== null && before.item <= 0, `the item is above the screen (${JSON.stringify(before)})`);
    state = await waitForVerdict(1);
    await waitForPlate();
    const after = await where();
    const moved = JSON.stringify({ before, after });
    assert.ok(after.item !== null, `the focus came back to an item on the plate (${moved})`);
    assert.ok(after.item <= 0, `the page was not pulled up to the focused item (${moved})`);
    assert.ok(Math.abs(after.bite - before.bite) < 100, `the bite stayed where the person put it (${moved})`);
    const seen = await page.evaluate(() => window.__phasesSeen);
    const order = seen.map((p) => PHASE_ORDER.indexOf(p));
    assert.deepEqual([...order].sort((a, b) => a - b), order, `phases in order: ${seen}`);
    for (const phase of ['APPROACH', 'DESCEND', 'EXTRACT', 'DONE'].map((p) => `ACQUIRE_PHASE_${p}`)) {
      assert.ok(seen.includes(phase), `${phase} was shown (seen: ${seen})`);
    }
    const force = await page.evaluate(() => ({
      value: document.querySelector('.force-value').textContent,
      points: document.querySelector('.spark-line').getAttribute('points').split(' ').length,
    }));
    assert.match(force.value, /^\d+\.\d N$/);
    assert.ok(force.points > 5, `the force line has ${force.points} points`);
  });

  const byRobot = !OPERATOR && 'the console decides by itself (BITEWISE_CONSOLE_OPERATOR is not 1)';
  it('asks the operator about the food and the action, and takes a changed answer', { skip: byRobot }, async () => {
    const state = await waitForMeal(biteJudged(1), 30000, 'the question');
    const { number, outcome } = state.current;
    assert.ok(state.current.question, `the console asks the operator (bite ${number}: ${outcome}, ${state.message})`);
    const question = await page.$eval('.question-text', (p) => p.textContent);
    const food = state.current.food || `item ${state.current.item_index + 1}`;
    assert.ok(question.includes(food), `"${question}" names the food (${food})`);
    assert.ok(question.includes(state.current.action.name), `"${question}" names the action`);
    await screenshot(page, 'table-04-question', '.question');
    await checkAxe(page, 'the question');

    await press(page, '.question .yes');
    await waitIn(page, () => document.querySelector('.question .yes').getAttribute('aria-pressed') === 'true');
    assert.equal((await mealState()).current.answer, 'yes');
    await press(page, '.question .no');
    await waitIn(page, () => document.querySelector('.question .no').getAttribute('aria-pressed') === 'true');
    assert.equal(await page.$eval('.question .yes', (b) => b.getAttribute('aria-pressed')), 'false');
    assert.equal((await mealState()).current.answer, 'no');
    assert.match(await page.$eval('.answer-note', (p) => p.textContent), /Your answer: No/);
    await screenshot(page, 'table-05-answered', '.question');
    await checkAxe(page, 'the answered question');
  });

  it('shows the outcome the console decided', { skip: OPERATOR && 'the operator decides' }, async () => {
    const state = await mealState();
    assert.ok(['success', 'failure'].includes(state.current.outcome), `outcome ${state.current.outcome}`);
    assert.equal(await page.$eval('.bite', (b) => b.dataset.outcome), state.current.outcome);
    await screenshot(page, 'table-04-outcome', '.bite');
    await checkAxe(page, 'the outcome');
  });

  it('bites a tapped item and shows the bite again after a reload', async () => {
    await waitForPlate();
    const items = await page.$$('.plate-overlay .item');
    const index = items.length - 1; // another item than the keyboard's, when there is one
    await press(page, items[index], { tap: true });
    await waitForMeal((s) => s.current.number === 2, 20000, 'bite 2 to start');
    await page.reload({ waitUntil: 'domcontentloaded' });
    // The stream's first state repaints the running bite.
    await waitIn(page, () => document.querySelector('#bite-heading')?.textContent === 'Bite 2');
    const state = await waitForVerdict(2);
    assert.equal(state.current.item_index, index);
    await answerIfAsked(state, true);
  });

  it('says the connection is lost when the stream goes silent, and takes no bite until it is back', async () => {
    // The page's EventSource is wrapped (before its scripts run) so that the
    // test can mute it: the connection stays open and nothing arrives, as
    // when Wi-Fi drops without an error or the console hangs.
    await page.evaluateOnNewDocument(() => {
      const Real = window.EventSource;
      window.EventSource = class extends Real {
        addEventListener(type, listener, options) {
          super.addEventListener(type, (event) => window.__muteStream || listener(event), options);
        }
      };
    });
    await page.reload({ waitUntil: 'domcontentloaded' });
    await waitForPlate();
    await page.evaluate(() => {
      window.__muteStream = true;
    });
    await waitIn(page, () => document.querySelector('.connection').dataset.connection === 'lost', null, 15000);
    const lost = await page.evaluate(() => ({
      text: document.querySelector('.connection').textContent,
      choice: document.querySelector('#robots-choice').getAttribute('aria-disabled'),
      items: [...document.querySelectorAll('.plate-overlay .item')].map((e) => e.getAttribute('aria-disabled')),
    }));
    assert.match(lost.text, /^Connection lost: retrying… What is shown may be out of date, and the arm may be moving/);
    assert.equal(lost.choice, 'true', "the robot's choice waits for the stream");
    assert.ok(lost.items.every((d) => d === 'true'), 'no item takes a tap');
    await screenshot(page, 'table-05b-connection-lost', '.plate-card');
    await page.evaluate(() => {
      window.__muteStream = false;
    });
    await waitIn(page, () => document.querySelector('.connection').dataset.connection === 'live', null, 15000);
    await waitForPlate();
  });

  it('stops the arm during DESCEND with one request and shows the reply', async () => {
    await waitForPlate();
    await press(page, '#robots-choice');
    await currentPhase('ACQUIRE_PHASE_DESCEND');
    const postsBefore = record.stopPosts;
    await page.click('#stop-button'); // fixed on screen: no scrolling, no delay
    await waitIn(page, () => document.querySelector('#stop-status').dataset.wasMoving !== undefined, null, 10000);
    const stop = await page.evaluate(() => ({
      text: document.querySelector('#stop-status').textContent,
      wasMoving: document.querySelector('#stop-status').dataset.wasMoving,
      ms: Number(document.body.dataset.stopReplyMs),
      serverMs: Number(document.body.dataset.stopServerMs),
    }));
    console.log(`STOP: click to reply ${stop.ms} ms (page's clock), ${stop.serverMs} ms of it in the console`);
    assert.match(stop.text, /^Stopped/);
    assert.equal(stop.wasMoving, 'true', 'the arm was moving when STOP arrived');
    // The time is reported, not asserted: speed is measured by the benchmark
    // (scripts/bench_console.sh) on a quiet machine, not by a test that
    // shares the cores with whatever else runs.
    assert.ok(Number.isFinite(stop.ms) && stop.ms > 0, `STOP's reply time was measured (${stop.ms})`);
    assert.equal(record.stopPosts - postsBefore, 1, 'one press sends one POST /api/stop');

    const stopped = (s) => s.current.number === 3 && s.current.outcome === 'stopped';
    const state = await waitForMeal(stopped, 20000, 'the stopped bite');
    assert.ok(state.stopped || state.current.outcome === 'stopped');
    await waitIn(page, () => document.querySelector('.bite').dataset.outcome === 'stopped');
    await screenshot(page, 'table-06-stopped', '.bite');
    await checkAxe(page, 'the stopped bite');
  });

  it('clears the STOP line once a new bite moves the arm', async () => {
    // A stopped bite is not followed by a look (it may move the arm back to
    // its viewing pose): the person asks for it.
    await waitForMeal((s) => s.phase === 'failed' && !s.plate_fresh, 20000, 'the stopped bite to settle');
    // The plate says its items are from before the bite, and takes no tap.
    await waitIn(page, () => /seen before bite 3; look at the plate again/.test(document.querySelector('.plate-caption').textContent));
    await press(page, '#look-again');
    await waitForPlate();
    assert.match(await page.$eval('#stop-status', (e) => e.textContent), /^Stopped: the arm was moving and was halted at /);
    await press(page, '#robots-choice');
    await waitForMeal((s) => s.current.number === 4, 20000, 'bite 4 to start');
    await waitIn(page, () => document.querySelector('#stop-status').textContent === 'Stops the arm at once.');
    const state = await waitForVerdict(4);
    await answerIfAsked(state, true);
  });

  it('ends the meal and shows its summary in words that count right', async () => {
    await waitForMeal((s) => readyForBite(s) || !s.running, 60000, 'the stopped bite to settle');
    await press(page, '#end-meal');
    const state = await waitForMeal((s) => !s.running, 20000, 'the meal to end');
    await waitIn(page, () => document.querySelector('.table-view').dataset.running === 'false');
    const shown = await page.evaluate(() => ({
      text: document.querySelector('.summary-text').textContent,
      attempts: Number(document.querySelector('.summary').dataset.attempts),
      failures: Number(document.querySelector('.summary').dataset.failures),
      foods: [...document.querySelectorAll('.foods-table tbody tr')].map((tr) => ({
        food: tr.dataset.food,
        attempts: Number(tr.dataset.attempts),
        failures: Number(tr.dataset.failures),
      })),
    }));
    const { attempts, failures } = state.summary;
    assert.equal(shown.attempts, attempts);
    assert.equal(shown.failures, failures);
    const words = (n, one) => `${n} ${n === 1 ? one : `${one}s`}`;
    assert.equal(shown.text, `${words(attempts, 'attempt')}, ${words(failures, 'failure')}`);
    assert.equal(shown.foods.reduce((n, f) => n + f.attempts, 0), attempts);
    assert.equal(shown.foods.reduce((n, f) => n + f.failures, 0), failures);
    // Three bites were judged (the third was stopped).
    assert.equal(attempts, 3);
    await screenshot(page, 'table-07-summary', '.summary');
    await checkAxe(page, 'the summary');
  });

  it('tells the person to use the emergency stop when STOP has no reply', async () => {
    // The console's reply is held back 3 s (the page's fetch, wrapped): a
    // console that cannot answer, as a loaded or hung one would.
    await page.evaluate(() => {
      const real = window.fetch;
      window.__realFetch = real;
      window.fetch = (input, init) =>
        String(input).endsWith('/api/stop')
          ? new Promise((resolve) => setTimeout(resolve, 3000)).then(() => real(input, init))
          : real(input, init);
    });
    await page.click('#stop-button');
    await waitIn(page, () => /^No reply to STOP after 2 s: use the robot's own emergency stop/.test(
      document.querySelector('#stop-status').textContent), null, 10000);
    assert.equal(await page.$eval('#stop-status', (e) => e.className), 'stop-status failed');
    // The late reply still shows.
    await waitIn(page, () => /^Stopped: the arm was not moving/.test(
      document.querySelector('#stop-status').textContent), null, 10000);
    await page.evaluate(() => {
      window.fetch = window.__realFetch;
    });
  });

  it('left the console only for its own origin, with no page errors', async () => {
    assert.deepEqual(record.offOrigin, []);
    assert.deepEqual(record.errors, []);
    const latencies = await page.evaluate(() => window.__progressLatencies || []);
    if (latencies.length) {
      const sorted = [...latencies].sort((a, b) => a - b);
      const ms = (q) => (sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))] * 1000).toFixed(1);
      console.log(`progress paint latency over ${sorted.length} reports: median ${ms(0.5)} ms, p95 ${ms(0.95)} ms`);
    }
  });
});
