// The researcher view (#/research), read-only: the people, a person's failures
// per meal, the events (bites) of a meal page by page with their per-action
// estimates, a CSV download, and the health of the four services. What is
// chosen lives in the hash (#/research?user=...&meal=...&event=...), so the
// browser's Back button and bookmarks work.

import { getJSON, query, userPath } from './api.js';
import { h, keyed, setAttr, setText, show } from './dom.js';
import { count, int, learnerWord, threeDigits, when } from './format.js';
import { createFailuresChart } from './failures-chart.js';

const PAGE_SIZE = 50;

const researchHash = (params) => `#/research${query(params)}`;

function table(caption, headers, rows, attrs = {}) {
  return h(
    'table',
    attrs,
    h('caption', {}, caption),
    h('thead', {}, h('tr', {}, headers.map((text) => h('th', { scope: 'col' }, text)))),
    h('tbody', {}, rows),
  );
}

// A table wider than a phone scrolls sideways; the keyboard must reach that
// scroll too, so the box is focusable and named.
function scrollBox(label) {
  return h('div', { className: 'table-scroll', tabindex: '0', role: 'region', 'aria-label': label });
}

function errorLine(el, err) {
  setText(el, err ? err.message || String(err) : '');
  show(el, Boolean(err));
}

export function createResearchView() {
  const heading = h('h2', { id: 'research-heading', tabindex: '-1' }, 'Research');
  const intro = h('p', { className: 'hint' }, "Read only: what each person's model learned, meal by meal.");

  // --- people -----------------------------------------------------------------
  const peopleError = h('p', { className: 'error', hidden: true });
  const peopleList = h('ul', { className: 'link-list people-links' });
  const peopleSection = h(
    'section',
    { className: 'card', 'aria-labelledby': 'people-heading' },
    h('h3', { id: 'people-heading' }, 'People'),
    peopleError,
    peopleList,
  );

  // --- one person -------------------------------------------------------------
  const personHeading = h('h3', { id: 'person-heading', tabindex: '-1' });
  const personLine = h('p', { className: 'person-line' });
  const mealsError = h('p', { className: 'error', hidden: true });
  const chart = createFailuresChart();
  const mealsTable = scrollBox('Meals table');
  const personSection = h(
    'section',
    { className: 'card person', 'aria-labelledby': 'person-heading', hidden: true },
    personHeading,
    personLine,
    mealsError,
    chart.root,
    mealsTable,
  );

  // --- events of a meal -------------------------------------------------------
  const eventsHeading = h('h3', { id: 'events-heading', tabindex: '-1' }, 'Bites');
  const mealSelect = h('select', { id: 'meal-filter' });
  const contextsBox = h('input', { type: 'checkbox', id: 'csv-contexts' });
  const csvLink = h('a', { className: 'button-link', id: 'csv-link' }, 'Download CSV');
  const eventsError = h('p', { className: 'error', hidden: true });
  const eventsTable = scrollBox('Bites table');
  const pageLine = h('p', { className: 'page-line', 'aria-live': 'polite' });
  const prevButton = h('button', { type: 'button', className: 'secondary', id: 'events-prev' }, 'Previous page');
  const nextButton = h('button', { type: 'button', className: 'secondary', id: 'events-next' }, 'Next page');
  const eventsSection = h(
    'section',
    { className: 'card events', 'aria-labelledby': 'events-heading', hidden: true },
    eventsHeading,
    h(
      'div',
      { className: 'row filters' },
      h('label', { for: 'meal-filter' }, 'Meal'),
      mealSelect,
    ),
    h(
      'div',
      { className: 'row csv' },
      csvLink,
      h('label', { className: 'check', for: 'csv-contexts' }, contextsBox, ' include contexts'),
    ),
    eventsError,
    eventsTable,
    h('div', { className: 'row pager' }, prevButton, pageLine, nextButton),
  );

  // --- estimates of one bite ------------------------------------------------
  const estimatesHeading = h('h3', { id: 'estimates-heading', tabindex: '-1' }, 'Estimates');
  const estimatesError = h('p', { className: 'error', hidden: true });
  const estimatesLearner = h('p', { className: 'estimates-learner' });
  const estimatesTable = scrollBox('Estimates table');
  const estimatesSection = h(
    'section',
    { className: 'card estimates', 'aria-labelledby': 'estimates-heading', hidden: true },
    estimatesHeading,
    h(
      'p',
      { className: 'hint' },
      "Each action's predicted loss at this bite's context from the person's current model, as their learner " +
        'weighs it at a Select (lower is better), its width, and its lower bound (LinUCB, the default strategy, ' +
        'picks the action with the lowest).',
    ),
    estimatesLearner,
    estimatesError,
    estimatesTable,
  );

  // --- health ---------------------------------------------------------------
  const healthError = h('p', { className: 'error', hidden: true });
  const healthTable = scrollBox('Services table');
  const robotList = h('dl', { className: 'robot-status' });
  const healthButton = h('button', { type: 'button', className: 'secondary', id: 'health-refresh' }, 'Check again');
  const healthSection = h(
    'section',
    { className: 'card health', 'aria-labelledby': 'health-heading' },
    h('div', { className: 'row spread' }, h('h3', { id: 'health-heading' }, 'Services'), healthButton),
    healthError,
    healthTable,
    h('h4', {}, 'Robot'),
    robotList,
  );

  const root = h(
    'section',
    { className: 'view research-view', 'aria-labelledby': 'research-heading' },
    heading,
    intro,
    h(
      'div',
      { className: 'research-grid' },
      h('div', { className: 'col' }, peopleSection),
      h('div', { className: 'col col-wide' }, personSection, eventsSection, estimatesSection, healthSection),
    ),
  );

  // --- state ----------------------------------------------------------------
  let users = []; // User messages
  let route = { user: '', meal: '', event: '' };
  let meals = [];
  let pageTokens = ['']; // tokens of the pages seen so far; the last is the page on show
  let nextToken = '';
  let events = [];
  let loads = 0; // a newer load wins over an older one still on its way

  const actionNames = () => users.find((u) => u.user_id === route.user)?.config?.action_names || [];

  async function loadPeople() {
    try {
      const reply = await getJSON('/api/people');
      users = (reply?.users || []).slice().sort((a, b) => a.user_id.localeCompare(b.user_id));
      errorLine(peopleError, null);
    } catch (err) {
      errorLine(peopleError, err);
    }
    paintPeople();
  }

  function paintPeople() {
    keyed(peopleList, JSON.stringify([users.map((u) => [u.user_id, u.model_version]), route.user]), () =>
      users.length
        ? users.map((u) =>
            h(
              'li',
              {},
              h(
                'a',
                {
                  href: researchHash({ user: u.user_id }),
                  'aria-current': u.user_id === route.user ? 'true' : null,
                  'data-user': u.user_id,
                  'data-focus-key': `user-${u.user_id}`,
                },
                u.user_id,
              ),
              h('span', { className: 'hint' }, ` ${count(int(u.model_version), 'bite')} learned`),
            ),
          )
        : h('li', { className: 'hint' }, 'Nobody yet.'),
    );
  }

  async function loadHealth() {
    setAttr(healthButton, 'aria-busy', 'true');
    try {
      const reply = await getJSON('/api/health');
      errorLine(healthError, null);
      const services = reply?.services || [];
      healthTable.replaceChildren(
        table(
          'Health of the four services',
          ['Service', 'Address', 'Status', 'Detail'],
          services.map((svc) =>
            h(
              'tr',
              { 'data-service': svc.service, 'data-status': svc.status },
              h('th', { scope: 'row' }, svc.service),
              h('td', {}, svc.address),
              h('td', { className: `status status-${String(svc.status).toLowerCase()}` }, svc.status),
              h('td', {}, svc.detail),
            ),
          ),
          { className: 'health-table' },
        ),
      );
      const robot = reply?.robot || {};
      const facts = [
        ['Backend', robot.simulated ? 'simulation' : robot.arm_name || 'hardware'],
        ['Arm ready', robot.arm_ready ? 'yes' : 'no'],
        ['Busy with', robot.busy_with || 'nothing'],
        ['Force sensor', `${robot.ft_state || '–'}${robot.ft_rate_hz ? `, ${Math.round(robot.ft_rate_hz)} Hz` : ''}`],
        ['Sensor counter', robot.ft_counter_state || '–'],
      ];
      if (robot.ft_counter_problem) facts.push(['Counter problem', robot.ft_counter_problem]);
      if (reply?.robot_error) facts.unshift(['Robot', reply.robot_error]);
      robotList.replaceChildren(...facts.flatMap(([k, v]) => [h('dt', {}, k), h('dd', {}, v)]));
    } catch (err) {
      errorLine(healthError, err);
    } finally {
      healthButton.removeAttribute('aria-busy');
    }
  }
  healthButton.addEventListener('click', loadHealth);

  async function loadMeals(load) {
    setText(personHeading, route.user);
    const user = users.find((u) => u.user_id === route.user);
    setText(
      personLine,
      user
        ? `Learns with ${learnerWord(user.config?.learner)}. ${count(int(user.model_version), 'bite')} learned, ${count(int(user.pending_events), 'bite')} pending.`
        : '',
    );
    try {
      const reply = await getJSON(`${userPath(route.user)}/meals`);
      if (load !== loads) return;
      meals = reply?.meals || [];
      errorLine(mealsError, null);
    } catch (err) {
      if (load !== loads) return;
      meals = [];
      errorLine(mealsError, err);
    }
    chart.update(meals);
    mealsTable.replaceChildren(
      table(
        'Attempts and failures per meal',
        ['#', 'Meal', 'First bite', 'Attempts', 'Failures', 'Pending', 'Bites'],
        meals.map((m, i) =>
          h(
            'tr',
            {
              'data-meal-id': m.meal_id,
              'data-attempts': m.attempts,
              'data-failures': m.failures,
              'data-pending': m.pending ?? 0,
            },
            h('td', {}, i + 1),
            h('th', { scope: 'row' }, m.meal_id),
            h('td', {}, when(m.first_selected_at)),
            h('td', {}, m.attempts),
            h('td', {}, m.failures),
            h('td', {}, m.pending ?? 0),
            h(
              'td',
              {},
              h(
                'a',
                { href: researchHash({ user: route.user, meal: m.meal_id }), 'aria-label': `Bites of ${m.meal_id}` },
                'Bites',
              ),
            ),
          ),
        ),
        { className: 'meals-table' },
      ),
    );
    keyed(mealSelect, JSON.stringify([meals.map((m) => m.meal_id), route.meal]), () => [
      h('option', { value: '' }, 'All meals'),
      ...meals.map((m) => h('option', { value: m.meal_id, selected: m.meal_id === route.meal }, m.meal_id)),
      // A meal named in the hash that has no completed bite still filters.
      route.meal && !meals.some((m) => m.meal_id === route.meal)
        ? h('option', { value: route.meal, selected: true }, route.meal)
        : null,
    ]);
    mealSelect.value = route.meal;
  }

  let keepFocus = false; // the select changed the hash: leave the focus on it
  mealSelect.addEventListener('change', () => {
    keepFocus = true;
    location.hash = researchHash({ user: route.user, meal: mealSelect.value });
  });

  function paintCsv() {
    const params = { meal_id: route.meal };
    if (contextsBox.checked) params.contexts = '1';
    csvLink.href = `${userPath(route.user)}/events.csv${query(params)}`;
    setAttr(csvLink, 'download', `${route.user}${route.meal ? `-${route.meal}` : ''}-events.csv`);
  }
  contextsBox.addEventListener('change', paintCsv);

  async function loadEvents(load) {
    const token = pageTokens[pageTokens.length - 1];
    setText(eventsHeading, route.meal ? `Bites of ${route.meal}` : 'All bites');
    setAttr(eventsTable, 'aria-busy', 'true');
    try {
      const reply = await getJSON(
        `${userPath(route.user)}/events${query({ meal_id: route.meal, page_size: PAGE_SIZE, page_token: token })}`,
      );
      if (load !== loads) return;
      events = reply?.events || [];
      nextToken = reply?.next_page_token || '';
      errorLine(eventsError, null);
    } catch (err) {
      if (load !== loads) return;
      events = [];
      nextToken = '';
      errorLine(eventsError, err);
    }
    eventsTable.removeAttribute('aria-busy');
    paintEvents();
  }

  function paintEvents() {
    const names = actionNames();
    const first = (pageTokens.length - 1) * PAGE_SIZE;
    eventsTable.replaceChildren(
      table(
        route.meal ? `Bites of ${route.meal}, oldest first` : 'All bites, oldest first',
        ['Time', 'Meal', 'Item', 'Action', 'Loss', 'Completed', 'Estimates'],
        events.map((e) =>
          h(
            'tr',
            {
              'data-event-id': e.event_id,
              'data-meal-id': e.meal_id,
              'data-completed': String(e.completed),
              'data-loss': e.loss,
              'aria-current': e.event_id === route.event ? 'true' : null,
            },
            h('td', {}, when(e.selected_at)),
            h('td', {}, e.meal_id),
            h('td', {}, e.item_label),
            h('td', {}, names[e.action] ?? `action ${e.action}`),
            h('td', {}, e.completed ? Number(e.loss).toFixed(2) : '–'),
            h('td', {}, e.completed ? 'yes' : 'pending'),
            h(
              'td',
              {},
              h(
                'a',
                {
                  href: researchHash({ user: route.user, meal: route.meal, event: e.event_id }),
                  'aria-label': `Estimates for event ${e.event_id}`,
                },
                'Estimates',
              ),
            ),
          ),
        ),
        { className: 'events-table' },
      ),
    );
    setText(
      pageLine,
      events.length ? `Bites ${first + 1} to ${first + events.length}` : first ? 'No more bites.' : 'No bites yet.',
    );
    setAttr(prevButton, 'aria-disabled', pageTokens.length > 1 ? null : 'true');
    setAttr(nextButton, 'aria-disabled', nextToken ? null : 'true');
  }

  prevButton.addEventListener('click', () => {
    if (pageTokens.length <= 1) return;
    pageTokens.pop();
    loadEvents(++loads);
  });
  nextButton.addEventListener('click', () => {
    if (!nextToken) return;
    pageTokens.push(nextToken);
    loadEvents(++loads);
  });

  async function loadEstimates(load) {
    setText(estimatesHeading, `Estimates for event ${route.event}`);
    try {
      const reply = await getJSON(`${userPath(route.user)}/estimates${query({ event_id: route.event })}`);
      if (load !== loads) return;
      errorLine(estimatesError, null);
      const chosen = events.find((e) => e.event_id === route.event)?.action;
      const estimates = reply?.estimates || [];
      setText(
        estimatesLearner,
        `${learnerWord(reply?.learner)}, model after ${count(int(reply?.model_version), 'bite')} learned.`,
      );
      const fixed = (x) => threeDigits(Number(x ?? 0));
      estimatesTable.replaceChildren(
        table(
          `Estimates per action for event ${route.event}`,
          ['Action', 'Predicted loss', 'Width', 'Lower bound', 'Bites learned'],
          estimates.map((e) =>
            h(
              'tr',
              { 'data-action': e.action, className: e.action === chosen ? 'chosen' : null },
              h('th', { scope: 'row' }, e.action_name, e.action === chosen ? ' (chosen)' : ''),
              h('td', {}, fixed(e.predicted_loss)),
              h('td', {}, fixed(e.width)),
              h('td', {}, fixed(e.lcb)),
              h('td', {}, int(e.count)),
            ),
          ),
          { className: 'estimates-table' },
        ),
      );
    } catch (err) {
      if (load !== loads) return;
      estimatesTable.replaceChildren();
      setText(estimatesLearner, '');
      errorLine(estimatesError, err);
    }
  }

  let opened = false;

  /**
   * Shows what `params` (from the hash) choose. `moved`: a link on this view
   * was followed; `entered`: the view was just switched to (fresh numbers).
   */
  async function showRoute(params, { moved = false, entered = false } = {}) {
    const next = { user: params.get('user') || '', meal: params.get('meal') || '', event: params.get('event') || '' };
    const first = !opened || entered;
    const fromSelect = keepFocus;
    keepFocus = false;
    if (first) {
      opened = true;
      loadHealth();
      await loadPeople();
    }
    const userChanged = first || next.user !== route.user;
    const mealChanged = userChanged || next.meal !== route.meal;
    const eventChanged = mealChanged || next.event !== route.event;
    route = next;
    paintPeople();
    show(personSection, Boolean(route.user));
    show(eventsSection, Boolean(route.user));
    show(estimatesSection, Boolean(route.user && route.event));
    if (!route.user) return;
    const load = ++loads;
    paintCsv();
    if (userChanged) await loadMeals(load);
    else if (mealChanged) mealSelect.value = route.meal;
    if (mealChanged) {
      pageTokens = [''];
      await loadEvents(load);
    } else if (eventChanged) {
      paintEvents(); // moves the row marked as current
    }
    if (route.event && eventChanged) await loadEstimates(load);
    // After a click, take the keyboard to what it opened.
    if (moved && !fromSelect) {
      if (eventChanged && route.event) estimatesHeading.focus();
      else if (mealChanged && !userChanged) eventsHeading.focus();
      else personHeading.focus();
    }
  }

  return { root, heading, show: showRoute };
}
