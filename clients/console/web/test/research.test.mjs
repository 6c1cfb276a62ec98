// The researcher view on a real bitewise-console: a person's failures per
// meal (chart and table) against ListEvents (every page), a meal's bites and
// a bite's estimates, the CSV download against ListEvents, paging, the
// services' health, axe-core and screenshots. Its data: two short meals
// played through the console's API for a person of its own.

import assert from 'node:assert/strict';
import { after, before, describe, it } from 'node:test';
import {
  BASE,
  SKIP,
  api,
  checkAxe,
  launchBrowser,
  listAllEvents,
  mealsFromEvents,
  openPage,
  press,
  parseCsv,
  playMealByApi,
  screenshot,
  screenshotDirectory,
  waitIn,
} from './helpers.mjs';

const EVENT_FIELDS = [
  'event_id',
  'user_id',
  'meal_id',
  'item_label',
  'action',
  'propensity',
  'completed',
  'loss',
  'posthoc',
  'model_version',
  'selected_at',
  'updated_at',
  'context',
];

/** One CSV cell against the event's field, allowing for how CSV writes values. */
function sameValue(field, cell, value, actionNames) {
  if (field === 'action') return cell === String(value) || cell === actionNames[value];
  if (field === 'completed') return ['true', '1'].includes(cell.toLowerCase()) === Boolean(value);
  if (Array.isArray(value)) {
    // Repeated fields: one cell, values joined by ';' (or spaces).
    const cells = cell.split(/[;\s]+/).filter(Boolean).map(Number);
    return cells.length === value.length && cells.every((c, i) => c === Number(value[i]));
  }
  if (typeof value === 'number' || field === 'model_version') {
    return Math.abs(Number(cell) - Number(value)) <= 1e-9 * Math.max(1, Math.abs(Number(value)));
  }
  if (field.endsWith('_at')) {
    const a = Date.parse(cell);
    const b = Date.parse(value);
    // An unset timestamp: empty in CSV, the epoch in JSON.
    const unset = (v) => !v || Date.parse(v) === 0;
    return cell === value || (Number.isFinite(a) && a === b) || (unset(cell) && unset(value));
  }
  return cell === String(value);
}

/** Checks a CSV download against ListEvents' events; returns the header. */
function assertCsvMatches(text, events, actionNames, label) {
  const rows = parseCsv(text).filter((r) => r.length > 1 || r[0] !== '');
  assert.ok(rows.length >= 1, `${label}: the CSV has a header`);
  const [header, ...body] = rows;
  assert.ok(header.includes('event_id'), `${label}: the CSV has an event_id column (${header})`);
  assert.equal(body.length, events.length, `${label}: one row per event`);
  const checked = EVENT_FIELDS.filter((f) => header.includes(f));
  body.forEach((row, i) => {
    assert.equal(row.length, header.length, `${label}: row ${i + 1} has every column`);
    for (const field of checked) {
      const cell = row[header.indexOf(field)];
      assert.ok(
        sameValue(field, cell, events[i][field], actionNames),
        `${label}: row ${i + 1} ${field} is "${cell}", ListEvents says ${JSON.stringify(events[i][field])}`,
      );
    }
  });
  return header;
}

describe('researcher view', { skip: SKIP }, () => {
  let chromium;
  let page;
  let record;
  const person = `web-research-${Date.now().toString(36)}`;
  let actionNames = [];

  before(async () => {
    // Two meals of this person's own, so the numbers are known to exist.
    await playMealByApi(person, 2);
    await playMealByApi(person, 1);
    const users = (await api('/api/people')).users;
    actionNames = users.find((u) => u.user_id === person)?.config?.action_names || [];
    chromium = await launchBrowser();
    ({ page, record } = await openPage(chromium.browser));
    console.log(`screenshots in ${await screenshotDirectory()}`);
  });

  after(async () => {
    await chromium?.close();
  });

  it('shows failures per meal as ListEvents counts them, in the chart and the table', async () => {
    await page.goto(`${BASE}/#/research`, { waitUntil: 'domcontentloaded' });
    assert.equal(await page.$eval('#stop-button', (b) => b.textContent.trim()), 'STOP');
    await waitIn(page, (who) => document.querySelector(`.people-links a[data-user="${who}"]`), person);
    await press(page, `.people-links a[data-user="${person}"]`);
    await waitIn(page, () => document.querySelectorAll('.meals-table tbody tr').length > 0);

    const expected = mealsFromEvents(await listAllEvents(person));
    assert.equal(expected.length, 2, 'two meals were played');
    const rows = await page.$$eval('.meals-table tbody tr', (trs) =>
      trs.map((tr) => ({
        meal_id: tr.dataset.mealId,
        attempts: Number(tr.dataset.attempts),
        failures: Number(tr.dataset.failures),
        pending: Number(tr.dataset.pending),
      })),
    );
    assert.deepEqual(rows, expected);
    const chart = await page.$eval('figure.chart', (f) => ({
      meal_ids: JSON.parse(f.dataset.mealIds),
      attempts: JSON.parse(f.dataset.attempts),
      failures: JSON.parse(f.dataset.failures),
      canvas: Boolean(f.querySelector('canvas')),
    }));
    assert.deepEqual(chart, {
      meal_ids: expected.map((m) => m.meal_id),
      attempts: expected.map((m) => m.attempts),
      failures: expected.map((m) => m.failures),
      canvas: true,
    });
    assert.match(await page.$eval('.person-line', (p) => p.textContent), /^Learns with post hoc LinUCB\. /);
    await waitIn(page, () => document.querySelectorAll('.health-table tbody tr').length > 0);
    await screenshot(page, 'research-01-person', '.person');
    await checkAxe(page, 'a person in the researcher view');
  });

  it("lists a meal's bites and a bite's estimates", async () => {
    const meal = await page.$eval('.meals-table tbody tr', (tr) => tr.dataset.mealId);
    await press(page, `.meals-table tbody tr[data-meal-id="${meal}"] a`);
    await waitIn(
      page,
      (m) => {
        const rows = [...document.querySelectorAll('.events-table tbody tr')];
        return rows.length > 0 && rows.every((tr) => tr.dataset.mealId === m);
      },
      meal,
    );
    const events = await listAllEvents(person, meal);
    const shown = await page.$$eval('.events-table tbody tr', (trs) => trs.map((tr) => tr.dataset.eventId));
    assert.deepEqual(shown, events.slice(0, 50).map((e) => e.event_id));
    const firstRow = await page.$eval('.events-table tbody tr', (tr) => [...tr.cells].map((td) => td.textContent));
    assert.equal(firstRow[2], events[0].item_label);
    assert.equal(firstRow[3], actionNames[events[0].action] ?? `action ${events[0].action}`);

    const event = events[0].event_id;
    await press(page, `.events-table tbody tr[data-event-id="${event}"] a`);
    await waitIn(page, () => document.querySelectorAll('.estimates-table tbody tr').length > 0);
    const estimates = await api(
      `/api/people/${encodeURIComponent(person)}/estimates?event_id=${encodeURIComponent(event)}`,
    );
    const names = await page.$$eval('.estimates-table tbody th', (ths) =>
      ths.map((th) => th.textContent.replace(' (chosen)', '')),
    );
    assert.deepEqual(names, estimates.estimates.map((e) => e.action_name));
    // Each row is the learner's own estimate (BanditService.Estimate), to the
    // shown digits, and the learner is named.
    const cells = await page.$$eval('.estimates-table tbody tr', (trs) =>
      trs.map((tr) => [...tr.cells].slice(1).map((td) => td.textContent)),
    );
    assert.deepEqual(
      cells,
      estimates.estimates.map((e) => [
        ...[e.predicted_loss, e.width, e.lcb].map((x) => {
          const rounded = Number(Number(x ?? 0).toPrecision(3));
          return rounded === 0 ? '0' : String(rounded);
        }),
        String(Number(e.count ?? 0)),
      ]),
    );
    assert.ok(Number(estimates.estimates[0].width) > 0, 'the estimates carry their widths');
    assert.equal(estimates.learner, 'LEARNER_POSTHOC', 'a new person learns with post hoc LinUCB');
    assert.match(
      await page.$eval('.estimates-learner', (p) => p.textContent),
      /^post hoc LinUCB, model after \d+ bites? learned\.$/,
    );
    await screenshot(page, 'research-02-estimates', '.estimates');
    await checkAxe(page, "a bite's estimates");
  });

  it('downloads the CSV that ListEvents pages hold, with and without contexts', async () => {
    const meal = await page.$eval('#meal-filter', (s) => s.value);
    const href = await page.$eval('#csv-link', (a) => a.href);
    assert.equal(new URL(href).origin, new URL(BASE).origin);
    assert.equal(new URL(href).searchParams.get('meal_id'), meal);
    const csv = await (await fetch(href)).text();
    const plain = assertCsvMatches(csv, await listAllEvents(person, meal), actionNames, `CSV of ${meal}`);

    await press(page, '#csv-contexts');
    const withContexts = await page.$eval('#csv-link', (a) => a.href);
    assert.equal(new URL(withContexts).searchParams.get('contexts'), '1');
    const full = assertCsvMatches(
      await (await fetch(withContexts)).text(),
      await listAllEvents(person, meal, { contexts: true }),
      actionNames,
      `CSV of ${meal} with contexts`,
    );
    assert.ok(full.length >= plain.length, 'contexts add columns');

    // All meals, without contexts again.
    await press(page, '#csv-contexts');
    await page.select('#meal-filter', '');
    await waitIn(page, () => new URL(document.querySelector('#csv-link').href).searchParams.get('meal_id') === null);
    const all = await (await fetch(await page.$eval('#csv-link', (a) => a.href))).text();
    assertCsvMatches(all, await listAllEvents(person), actionNames, 'CSV of every meal');
  });

  it('pages through events 50 at a time', async (t) => {
    // Only someone with more than a page of events shows paging.
    const users = (await api('/api/people')).users;
    const big = users.find((u) => Number(u.model_version) + Number(u.pending_events) > 50);
    if (!big) {
      t.skip('nobody has more than 50 events');
      return;
    }
    const events = await listAllEvents(big.user_id);
    // Only the hash changes: the page stays, and its table changes once loaded.
    await page.goto(`${BASE}/#/research?user=${encodeURIComponent(big.user_id)}`, { waitUntil: 'domcontentloaded' });
    await waitIn(
      page,
      (id) => document.querySelector('.events-table tbody tr')?.dataset.eventId === id,
      events[0].event_id,
    );
    const first = await page.$$eval('.events-table tbody tr', (trs) => trs.map((tr) => tr.dataset.eventId));
    assert.deepEqual(first, events.slice(0, 50).map((e) => e.event_id));
    await press(page, '#events-next');
    await waitIn(
      page,
      (id) => document.querySelector('.events-table tbody tr')?.dataset.eventId === id,
      events[50].event_id,
    );
    const second = await page.$$eval('.events-table tbody tr', (trs) => trs.map((tr) => tr.dataset.eventId));
    assert.deepEqual(second, events.slice(50, 100).map((e) => e.event_id));
  });

  it("shows the four services' health", async () => {
    const health = await api('/api/health');
    const rows = await page.$$eval('.health-table tbody tr', (trs) =>
      trs.map((tr) => ({ service: tr.dataset.service, status: tr.dataset.status })),
    );
    assert.equal(rows.length, 4);
    assert.deepEqual(rows, health.services.map((s) => ({ service: s.service, status: s.status })));
  });

  it('left the console only for its own origin, with no page errors', () => {
    assert.deepEqual(record.offOrigin, []);
    assert.deepEqual(record.errors, []);
  });
});
