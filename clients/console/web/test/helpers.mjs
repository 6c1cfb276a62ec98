// Shared by the browser tests: the console under test, a headless Chromium,
// axe-core, screenshots, and the console's own API for setting up and
// checking what the page shows. Nothing here stands in for the console: the
// tests run against a real bitewise-console at BITEWISE_CONSOLE_URL.

import assert from 'node:assert/strict';
import { mkdir, mkdtemp, rm } from 'node:fs/promises';
import { tmpdir } from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const here = path.dirname(fileURLToPath(import.meta.url));

export const BASE = (process.env.BITEWISE_CONSOLE_URL || '').replace(/\/+$/, '');
export const ORIGIN = BASE ? new URL(BASE).origin : '';
/** node:test's skip option: a reason when there is no console to test. */
export const SKIP = BASE
  ? false
  : 'BITEWISE_CONSOLE_URL is not set: start bitewise-console (scripts/console.sh) and point it there';
export const OPERATOR = process.env.BITEWISE_CONSOLE_OPERATOR === '1';

export const PHONE = { width: 360, height: 740 };
export const TABLET = { width: 1024, height: 768 };

const AXE_PATH = path.join(here, '..', 'node_modules', 'axe-core', 'axe.min.js');
const CHROMIUM = process.env.BITEWISE_CHROMIUM || '/usr/bin/chromium';

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

let screenshotDir = null;
export async function screenshotDirectory() {
  if (!screenshotDir) {
    screenshotDir = process.env.BITEWISE_SCREENSHOT_DIR || (await mkdtemp(path.join(tmpdir(), 'bitewise-screens-')));
    await mkdir(screenshotDir, { recursive: true });
  }
  return screenshotDir;
}

/** Headless Chromium with a fresh profile; close() also removes the profile. */
export async function launchBrowser() {
  const profile = await mkdtemp(path.join(tmpdir(), 'bitewise-chromium-'));
  const browser = await puppeteer.launch({
    executablePath: CHROMIUM,
    headless: true,
    userDataDir: profile,
    args: [
      '--headless=new',
      '--no-sandbox',
      '--disable-gpu',
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
  });
  return {
    browser,
    async close() {
      await browser.close();
      await rm(profile, { recursive: true, force: true });
    },
  };
}

/**
 * A page at phone size with touch. Records every request the page makes
 * (`offOrigin` collects those that leave the console's origin), uncaught page
 * errors, and the STOP requests.
 */
export async function openPage(browser, size = PHONE) {
  const page = await browser.newPage();
  // axe-core is injected as an inline script; a console that forbids inline
  // scripts (CSP) must not stop the check.
  await page.setBypassCSP(true);
  await page.setViewport({ ...size, hasTouch: true });
  const record = { offOrigin: [], errors: [], stopPosts: 0, requests: [] };
  page.on('request', (request) => {
    const url = request.url();
    record.requests.push(`${request.method()} ${url}`);
    if (!url.startsWith('data:') && new URL(url).origin !== ORIGIN) record.offOrigin.push(url);
    if (request.method() === 'POST' && new URL(url).pathname === '/api/stop') record.stopPosts += 1;
  });
  page.on('pageerror', (err) => record.errors.push(err.message));
  return { page, record };
}

/** Runs axe-core on the page as it is; fails on serious or critical findings. */
export async function checkAxe(page, label) {
  if (!(await page.evaluate(() => typeof window.axe === 'object'))) {
    await page.addScriptTag({ path: AXE_PATH });
  }
  const violations = await page.evaluate(async () => {
    const result = await window.axe.run(document, { resultTypes: ['violations'] });
    return result.violations.map((v) => ({
      id: v.id,
      impact: v.impact,
      help: v.help,
      nodes: v.nodes.slice(0, 5).map((n) => n.target.join(' ')),
    }));
  });
  const bad = violations.filter((v) => v.impact === 'serious' || v.impact === 'critical');
  for (const v of violations.filter((x) => !bad.includes(x))) {
    console.log(`axe (${label}, ${v.impact}): ${v.id}: ${v.help} at ${v.nodes.join(', ')}`);
  }
  assert.deepEqual(bad, [], `axe on ${label}: serious or critical violations`);
}

/**
 * Screenshots the page at phone and tablet size (what a person sees, with
 * `selector` scrolled into view), then returns to phone size.
 */
export async function screenshot(page, name, selector) {
  const dir = await screenshotDirectory();
  for (const size of [PHONE, TABLET]) {
    await page.setViewport({ ...size, hasTouch: true });
    // STOP is on every screen, in every state.
    const stop = await page.$eval('#stop-button', (b) => {
      const box = b.getBoundingClientRect();
      return box.width >= 44 && box.height >= 44 && box.top >= 0 && box.bottom <= innerHeight;
    });
    assert.ok(stop, `STOP is on screen (${name}, ${size.width}x${size.height})`);
    if (selector) {
      await page.evaluate(
        (sel) => document.querySelector(sel)?.scrollIntoView({ block: 'center', inline: 'nearest' }),
        selector,
      );
    }
    await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
    await page.screenshot({ path: path.join(dir, `${name}-${size.width}x${size.height}.png`) });
  }
  await page.setViewport({ ...PHONE, hasTouch: true });
}

/**
 * Clicks (or taps) an element after scrolling it to the middle of the
 * screen: puppeteer only scrolls elements outside the viewport, and one near
 * the bottom would sit under the fixed STOP bar, which would take the click.
 */
export async function press(page, selector, { tap = false } = {}) {
  const element = typeof selector === 'string' ? await page.waitForSelector(selector, { visible: true }) : selector;
  await element.evaluate((el) => el.scrollIntoView({ block: 'center', inline: 'nearest' }));
  await (tap ? element.tap() : element.click());
}

/** Waits for `fn` to hold in the page, re-checking on every DOM change. */
export function waitIn(page, fn, arg, timeout = 30000) {
  return page.waitForFunction(fn, { polling: 'mutation', timeout }, arg);
}

/**
 * Presses Tab until the focus is on an element matching `selector`, checking
 * on the way that every focused element shows its focus. Returns the number
 * of presses.
 */
export async function tabTo(page, selector, maxPresses = 60) {
  for (let presses = 1; presses <= maxPresses; presses++) {
    await page.keyboard.press('Tab');
    const state = await page.evaluate((sel) => {
      const el = document.activeElement;
      if (!el || el === document.body) return { body: true };
      const style = getComputedStyle(el);
      const name = (el.getAttribute('aria-label') || el.textContent).trim().slice(0, 30);
      return {
        body: false,
        hit: el.matches(sel),
        what: `${el.tagName.toLowerCase()}#${el.id}.${el.getAttribute('class') || ''} "${name}"`,
        visible: (style.outlineStyle !== 'none' && parseFloat(style.outlineWidth) > 0) || style.boxShadow !== 'none',
      };
    }, selector);
    if (state.body) continue;
    assert.ok(state.visible, `keyboard focus is not visible on ${state.what}`);
    if (state.hit) return presses;
  }
  throw new Error(`Tab never reached ${selector} in ${maxPresses} presses`);
}

// --- the console's API, for set-up and for checking the page against it ----

export class ConsoleError extends Error {
  constructor(message, status) {
    super(message);
    this.status = status;
  }
}

export async function api(pathname, body) {
  const init =
    body === undefined
      ? {}
      : {
          method: 'POST',
          headers: { 'X-Bitewise-Request': '1', 'Content-Type': 'application/json' },
          body: JSON.stringify(body),
        };
  const response = await fetch(`${BASE}${pathname}`, init);
  const text = await response.text();
  let json = null;
  try {
    json = JSON.parse(text);
  } catch {
    json = null;
  }
  if (!response.ok) {
    throw new ConsoleError(
      `${init.method || 'GET'} ${pathname}: HTTP ${response.status}: ${json?.error ?? text}`,
      response.status,
    );
  }
  return json ?? text;
}

/** POSTs, retrying while the console answers 409 (a bite still finishing). */
export async function postWhenFree(pathname, body, timeout = 60000) {
  const until = Date.now() + timeout;
  for (;;) {
    try {
      return await api(pathname, body);
    } catch (err) {
      if (err.status !== 409 || Date.now() > until) throw err;
      await sleep(200);
    }
  }
}

export const mealState = () => api('/api/meal');

/** Polls the meal until `done(state)` holds. */
export async function waitForMeal(done, timeout = 60000, what = 'the meal') {
  const until = Date.now() + timeout;
  let state;
  while (Date.now() < until) {
    state = await mealState();
    if (done(state)) return state;
    await sleep(100);
  }
  throw new Error(`timed out waiting for ${what}; last phase ${state?.phase}, message "${state?.message}"`);
}

/**
 * The plate is on show and a tap would start a bite: a look no bite has
 * used. The console looks again after each bite that went well; after a
 * failed or stopped bite the phase stays "failed" until "Look at the plate
 * again".
 */
export const readyForBite = (s) => s.running && s.phase === 'choosing' && s.plate_fresh === true;

/** The bite `number` has come to its verdict, or to the operator's question. */
export const biteJudged = (number) => (s) =>
  s.bite >= number &&
  s.current?.number === number &&
  (Boolean(s.current.question) || (s.current.outcome !== '' && s.current.outcome !== 'pending'));

/** Ends whatever meal a previous run left running. */
export async function endAnyMeal() {
  const state = await mealState();
  if (!state.running) return;
  await postWhenFree('/api/meal/end', {});
  await waitForMeal((s) => !s.running, 10000, 'the meal to end');
}

/** Every event ListEvents has for `user` (all pages), oldest first. */
export async function listAllEvents(user, mealId = '', { contexts = false } = {}) {
  const events = [];
  let token = '';
  for (let pages = 0; pages < 1000; pages++) {
    const params = new URLSearchParams({ page_size: '50' });
    if (mealId) params.set('meal_id', mealId);
    if (token) params.set('page_token', token);
    if (contexts) params.set('contexts', '1');
    const reply = await api(`/api/people/${encodeURIComponent(user)}/events?${params}`);
    events.push(...(reply.events || []));
    token = reply.next_page_token || '';
    if (!token) return events;
  }
  throw new Error('ListEvents never ended');
}

/**
 * Attempts, failures and pending bites per meal from events, in the order
 * meals first appear: a completed event is an attempt, and a failure when its
 * loss is at least 0.5 (losses are 0 or 1 for food that did or did not come
 * up); an event never completed is pending.
 */
export function mealsFromEvents(events) {
  const meals = new Map();
  for (const e of events) {
    if (!meals.has(e.meal_id)) meals.set(e.meal_id, { meal_id: e.meal_id, attempts: 0, failures: 0, pending: 0 });
    if (!e.completed) {
      meals.get(e.meal_id).pending += 1;
      continue;
    }
    const m = meals.get(e.meal_id);
    m.attempts += 1;
    if (Number(e.loss) >= 0.5) m.failures += 1;
  }
  return [...meals.values()];
}

/**
 * Plays a meal through the API (no browser): `bites` bites of the robot's
 * choice, answering the operator's question when asked (yes, no, yes...),
 * then ends it. Returns the final MealState.
 */
export async function playMealByApi(user, bites) {
  await endAnyMeal();
  await api('/api/meals', { user_id: user });
  let state = await waitForMeal((s) => readyForBite(s) || !s.running, 30000, 'the first look at the plate');
  for (let n = 1; n <= bites && state.running; n++) {
    const number = state.bite + 1;
    await postWhenFree('/api/meal/bite', { item_index: -1 });
    state = await waitForMeal((s) => biteJudged(number)(s) || !s.running, 60000, `bite ${number}`);
    if (state.current?.question) {
      await api('/api/meal/answer', { event_id: state.current.event_id, success: n % 2 === 1 });
    }
    state = await waitForMeal((s) => readyForBite(s) || !s.running, 60000, `the plate after bite ${number}`);
  }
  if (state.running) await postWhenFree('/api/meal/end', {});
  return waitForMeal((s) => !s.running, 10000, 'the meal to end');
}

/** RFC 4180 CSV: rows of fields (quoted fields may hold commas, quotes, newlines). */
export function parseCsv(text) {
  const rows = [];
  let row = [];
  let field = '';
  let quoted = false;
  for (let i = 0; i < text.length; i++) {
    const c = text[i];
    if (quoted) {
      if (c === '"' && text[i + 1] === '"') {
        field += '"';
        i++;
      } else if (c === '"') quoted = false;
      else field += c;
    } else if (c === '"') quoted = true;
    else if (c === ',') {
      row.push(field);
      field = '';
    } else if (c === '\n' || c === '\r') {
      if (c === '\r' && text[i + 1] === '\n') i++;
      row.push(field);
      rows.push(row);
      row = [];
      field = '';
    } else field += c;
  }
  if (field !== '' || row.length) {
    row.push(field);
    rows.push(row);
  }
  return rows;
}
