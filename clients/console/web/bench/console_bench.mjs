// Speed of bitewise-console's page as a browser meets it, against a running
// console at BITEWISE_CONSOLE_URL (scripts/bench_console.sh starts one):
//   - cold page loads: bytes transferred and time until the page is usable;
//   - live progress: how late each Acquire progress report reaches the screen;
//   - STOP: click to reply, as the page measures it, during the arm's motion.
// Prints a markdown table with the targets beside the numbers. Exits non-zero
// only on errors: a missed target is reported, not failed.
//
//   node bench/console_bench.mjs [--loads=10] [--bites=5] [--stops=10]

import {
  BASE,
  PHONE,
  api,
  biteJudged,
  endAnyMeal,
  launchBrowser,
  playMealByApi,
  postWhenFree,
  readyForBite,
  waitForMeal,
  waitIn,
} from '../test/helpers.mjs';

const arg = (name, fallback) => {
  const found = process.argv.find((a) => a.startsWith(`--${name}=`));
  return found ? Number(found.split('=')[1]) : fallback;
};
const LOADS = arg('loads', 10);
const BITES = arg('bites', 5);
const STOPS = arg('stops', 10);

// Nearest-rank percentile: with 10 samples the p95 is the largest.
function stats(xs) {
  const s = [...xs].sort((a, b) => a - b);
  const at = (p) => s[Math.min(s.length - 1, Math.ceil((p / 100) * s.length) - 1)];
  return { n: s.length, median: at(50), p95: at(95), max: s[s.length - 1] };
}

/**
 * Runs in the page before its own scripts: notes performance.now() (ms since
 * navigation start) at the first frame in which a person can start a meal:
 * the start form is shown (the first MealState arrived, no meal running) and
 * the person list has loaded. The app has no "ready" marker of its own; STOP
 * alone works earlier, from the HTML.
 */
function markUsable() {
  const usable = () => {
    const start = document.querySelector('.start');
    const people = document.querySelector('.people-status');
    return start && !start.closest('[hidden]') && people && !people.textContent.startsWith('Loading');
  };
  new MutationObserver((_, observer) => {
    if (!usable()) return;
    observer.disconnect();
    requestAnimationFrame(() => {
      window.__usableMs = performance.now();
    });
  }).observe(document, { subtree: true, childList: true, attributes: true, characterData: true });
}

/** One load in a fresh browser context (its own empty cache), cache disabled too. */
async function coldLoad(browser) {
  const context = await browser.createBrowserContext();
  try {
    const page = await context.newPage();
    await page.setViewport({ ...PHONE, hasTouch: true });
    const cdp = await page.createCDPSession();
    await cdp.send('Network.enable');
    await cdp.send('Network.setCacheDisabled', { cacheDisabled: true });
    // Bytes on the wire, headers included. The event stream never finishes:
    // what it has received so far (its first MealState) is counted instead.
    const urls = new Map();
    const finished = new Map();
    const streamed = new Map();
    cdp.on('Network.requestWillBeSent', (e) => urls.set(e.requestId, e.request.url));
    cdp.on('Network.dataReceived', (e) =>
      streamed.set(e.requestId, (streamed.get(e.requestId) ?? 0) + e.encodedDataLength),
    );
    cdp.on('Network.responseReceived', (e) =>
      streamed.set(e.requestId, (streamed.get(e.requestId) ?? 0) + (e.response.encodedDataLength ?? 0)),
    );
    cdp.on('Network.loadingFinished', (e) => finished.set(e.requestId, e.encodedDataLength));
    await page.evaluateOnNewDocument(markUsable);
    await page.goto(`${BASE}/#/table`, { waitUntil: 'load' });
    const usableMs = Number(await (await page.waitForFunction(() => window.__usableMs, { timeout: 30000 })).jsonValue());
    // Where the time goes: the console's wait before app.js's first byte, and
    // the renderer's busy time (script, style, layout) during the load.
    const nav = await page.evaluate(() => {
      const n = performance.getEntriesByType('navigation')[0];
      const js = performance.getEntriesByType('resource').find((r) => new URL(r.name).pathname === '/app.js');
      return { dcl: n.domContentLoadedEventEnd, load: n.loadEventEnd, jsWait: js ? js.responseStart - js.requestStart : NaN };
    });
    const m = await page.metrics();
    const busyMs = (m.ScriptDuration + m.RecalcStyleDuration + m.LayoutDuration) * 1000;
    const perUrl = new Map();
    for (const [id, url] of urls) {
      const bytes = finished.get(id) ?? streamed.get(id) ?? 0;
      const path = new URL(url).pathname;
      perUrl.set(path, (perUrl.get(path) ?? 0) + bytes);
    }
    const bytes = [...perUrl.values()].reduce((a, b) => a + b, 0);
    return { usableMs, ...nav, busyMs, bytes, perUrl };
  } finally {
    await context.close();
  }
}

/** Plays a meal through the API while the page shows it; the page's paint latencies, ms. */
async function progressLatencies(page) {
  await page.evaluate(() => {
    window.__progressLatencies.length = 0;
  });
  const person = `bench-${Date.now().toString(36)}`;
  const end = await playMealByApi(person, BITES);
  const seconds = await page.evaluate(() => [...window.__progressLatencies]);
  return { ms: seconds.map((s) => s * 1000), bites: end.bites?.length ?? 0 };
}

const MOVING = '.bite[data-outcome="pending"] li[data-phase="ACQUIRE_PHASE_DESCEND"][aria-current="step"]';

/** STOP pressed during DESCEND of `count` bites (the arm surely moving), one press each. */
async function stops(page, count) {
  await endAnyMeal();
  await api('/api/meals', { user_id: `bench-stop-${Date.now().toString(36)}` });
  const replies = [];
  for (let i = 0; i < count; i++) {
    let state = await waitForMeal((s) => readyForBite(s) || !s.running, 60000, 'the plate');
    if (!state.running) throw new Error(`the meal ended before STOP ${i + 1}: ${state.message} ${state.error}`);
    const number = state.bite + 1;
    await postWhenFree('/api/meal/bite', { item_index: -1 });
    // The page shows the arm descending: a progress report has reached the screen.
    await waitIn(page, (sel) => document.querySelector(sel), MOVING, 60000);
    await page.evaluate(() => {
      delete document.body.dataset.stopReplyMs;
      delete document.body.dataset.stopServerMs;
      delete document.querySelector('#stop-status').dataset.wasMoving;
    });
    await page.click('#stop-button');
    await waitIn(page, () => document.querySelector('#stop-status').dataset.wasMoving !== undefined, null, 10000);
    replies.push(
      await page.evaluate(() => ({
        ms: Number(document.body.dataset.stopReplyMs),
        serverMs: Number(document.body.dataset.stopServerMs),
        wasMoving: document.querySelector('#stop-status').dataset.wasMoving === 'true',
      })),
    );
    state = await waitForMeal((s) => biteJudged(number)(s) || !s.running, 30000, `stopped bite ${number}`);
    if (state.current?.outcome !== 'stopped') {
      console.error(`note: bite ${number} ended "${state.current?.outcome}" after STOP: ${state.current?.text}`);
    }
    // A stopped bite is not followed by a look of the console's own (a look
    // may move the arm): ask for it, as the person would.
    if (state.running && !state.plate_fresh) {
      await waitForMeal((s) => s.phase === 'failed' || !s.running, 30000, `bite ${number} to settle`);
      await postWhenFree('/api/meal/look', {});
    }
  }
  await postWhenFree('/api/meal/end', {});
  await waitForMeal((s) => !s.running, 10000, 'the meal to end');
  return replies;
}

const ms = (x) => (x < 10 ? x.toFixed(1) : Math.round(x).toString());
const kb = (b) => `${(b / 1000).toFixed(1)} KB`;
const trio = (s, f = ms) => `${f(s.median)} / ${f(s.p95)} / ${f(s.max)}`;
const verdict = (ok) => (ok ? 'met' : 'not met');

async function main() {
  if (!BASE) throw new Error('set BITEWISE_CONSOLE_URL to a running bitewise-console');
  await endAnyMeal(); // the page is usable only with no meal running
  const chromium = await launchBrowser();
  try {
    const loads = [];
    for (let i = 0; i < LOADS; i++) loads.push(await coldLoad(chromium.browser));
    const first = loads[0];
    const usable = stats(loads.map((l) => l.usableMs));
    const bytes = stats(loads.map((l) => l.bytes));

    const page = await chromium.browser.newPage();
    await page.setViewport({ ...PHONE, hasTouch: true });
    await page.evaluateOnNewDocument(markUsable);
    await page.goto(`${BASE}/#/table`, { waitUntil: 'load' });
    await page.waitForFunction(() => window.__usableMs, { timeout: 30000 });
    const progress = await progressLatencies(page);
    if (progress.ms.length === 0) throw new Error('the page painted no progress event during the meal');
    const paint = stats(progress.ms);
    const replies = await stops(page, STOPS);
    const click = stats(replies.map((r) => r.ms));
    const server = stats(replies.map((r) => r.serverMs));
    const moving = replies.filter((r) => r.wasMoving).length;

    const rows = [
      ['first load: bytes transferred', '≤ 500 KB', kb(first.bytes), verdict(first.bytes <= 500000)],
      [`${LOADS} cold loads: bytes, median / max`, '≤ 500 KB', `${kb(bytes.median)} / ${kb(bytes.max)}`, verdict(bytes.max <= 500000)],
      ['first load: usable (start form and people shown)', '≤ 1,000 ms', `${ms(first.usableMs)} ms`, verdict(first.usableMs <= 1000)],
      [`${LOADS} cold loads: usable, median / p95 / max`, '≤ 1,000 ms', `${trio(usable)} ms`, verdict(usable.max <= 1000)],
      [`${LOADS} cold loads: DOMContentLoaded / load, median`, '', `${ms(stats(loads.map((l) => l.dcl)).median)} / ${ms(stats(loads.map((l) => l.load)).median)} ms`, ''],
      [`${LOADS} cold loads: app.js request to first byte / renderer script+style+layout, median`, '', `${ms(stats(loads.map((l) => l.jsWait)).median)} / ${ms(stats(loads.map((l) => l.busyMs)).median)} ms`, ''],
      [`progress to screen, ${paint.n} reports in ${progress.bites} bites: median / p95 / max`, 'p95 ≤ 200 ms', `${trio(paint)} ms`, verdict(paint.p95 <= 200)],
      [`STOP click to reply (page), ${click.n} presses: median / p95 / max`, '(reported)', `${trio(click)} ms`, ''],
      ['STOP in the console (`reply_ms`): median / p95 / max', '', `${trio(server)} ms`, ''],
      ['STOP arrived while the arm was moving', '', `${moving} of ${replies.length}`, ''],
    ];
    console.log('\n| measure | target | result | |\n|---|---:|---:|---|');
    for (const row of rows) console.log(`| ${row.join(' | ')} |`);
    console.log(`\nusable, each load in order (ms): ${loads.map((l) => ms(l.usableMs)).join(', ')}`);
    console.log(`first load, per resource: ${[...first.perUrl].map(([p, b]) => `${p} ${kb(b)}`).join(', ')}`);
  } finally {
    await chromium.close();
  }
}

main().catch(async (err) => {
  console.error(`console_bench: ${err.stack || err}`);
  await endAnyMeal().catch(() => {});
  process.exitCode = 1;
});
