// The table view (#/table): for the caregiver and the person being fed, on a
// phone or tablet beside the plate. Everything on it is painted from the
// MealState the console streams; buttons only send requests.

import { ApiError, getJSON, postJSON } from './api.js';
import { createBitePanel } from './bite-panel.js';
import { h, keyed, setAttr, setText, show } from './dom.js';
import { count, int } from './format.js';
import { openMealStream } from './meal-stream.js';
import { createPlate } from './plate.js';
import { BITE_STARTED } from './stop.js';

export function createTableView() {
  let state = null;
  let busy = false; // one request from this view at a time
  // Hearing from the console now: actions wait for a live stream, so that no
  // one chooses from a plate or answers a question that is out of date.
  let connected = false;

  // --- what is happening (polite live region) -------------------------------
  const connection = h('p', { className: 'connection', 'data-connection': 'connecting' }, 'Connecting…');
  const message = h('p', { className: 'message' });
  const error = h('p', { className: 'error' });
  const notice = h('p', { className: 'error notice' }); // a request this page sent failed
  const live = h('div', { className: 'live', 'aria-live': 'polite' }, message, error, notice);

  const heading = h('h2', { id: 'table-heading', tabindex: '-1' }, 'Meal');
  const mealLine = h('p', { className: 'meal-line' });
  const top = h(
    'div',
    { className: 'card meal-head' },
    h('div', { className: 'row spread' }, heading, connection),
    mealLine,
    live,
  );

  function showNotice(text) {
    setText(notice, text);
  }

  async function request(path, body) {
    if (busy) return null;
    busy = true;
    showNotice('');
    paint();
    try {
      // The reply may carry a MealState, but the stream's is never older:
      // the page paints only what the stream says.
      return await postJSON(path, body);
    } catch (err) {
      showNotice(err instanceof ApiError ? err.message : String(err));
      return null;
    } finally {
      busy = false;
      paint();
    }
  }

  // --- choose the person and start ----------------------------------------
  const peopleList = h('div', { className: 'people' });
  const peopleStatus = h('p', { className: 'hint people-status' }, 'Loading the people…');
  const peopleSet = h(
    'fieldset',
    { className: 'people-set' },
    h('legend', {}, 'Who is eating?'),
    peopleStatus,
    peopleList,
  );
  const nameInput = h('input', {
    id: 'new-person-name',
    type: 'text',
    autocomplete: 'off',
    autocapitalize: 'none',
    spellcheck: 'false',
    enterkeyhint: 'done',
    'aria-describedby': 'new-person-hint',
  });
  const addButton = h('button', { type: 'button', className: 'secondary', id: 'add-person' }, 'Add');
  const newPerson = h(
    'div',
    { className: 'new-person' },
    h('label', { for: 'new-person-name' }, 'Someone new: their name'),
    h('div', { className: 'row' }, nameInput, addButton),
    h('p', { className: 'hint', id: 'new-person-hint' }, 'Their learning starts at their first bite.'),
  );
  const startButton = h('button', { type: 'button', className: 'primary big', id: 'start-meal' }, 'Start meal');
  const start = h(
    'section',
    { className: 'card start', 'aria-labelledby': 'start-heading' },
    h('h2', { id: 'start-heading' }, 'Start a meal'),
    peopleSet,
    newPerson,
    startButton,
  );

  let people = []; // user ids, known ones first
  const added = new Set(); // names added here, not yet known to the BanditService
  let chosenPerson = '';

  function paintPeople() {
    keyed(peopleList, JSON.stringify([people, [...added], chosenPerson]), () =>
      people.map((user) =>
        h(
          'label',
          { className: 'person' },
          h('input', {
            type: 'radio',
            name: 'person',
            value: user,
            checked: user === chosenPerson,
            'data-focus-key': `person-${user}`,
          }),
          h('span', {}, user, added.has(user) ? h('span', { className: 'tag' }, ' (new)') : null),
        ),
      ),
    );
  }

  async function loadPeople() {
    try {
      const reply = await getJSON('/api/people');
      const known = (reply?.users || []).map((u) => u.user_id).sort((a, b) => a.localeCompare(b));
      for (const user of known) added.delete(user);
      people = [...added, ...known];
      if (!chosenPerson && state?.user_id && people.includes(state.user_id)) chosenPerson = state.user_id;
      setText(peopleStatus, people.length ? '' : 'Nobody yet: add someone below.');
    } catch (err) {
      setText(peopleStatus, `Could not load the people: ${err.message}`);
    }
    show(peopleStatus, Boolean(peopleStatus.textContent));
    paintPeople();
  }

  peopleList.addEventListener('change', (event) => {
    if (event.target.name === 'person') chosenPerson = event.target.value;
  });

  function addPerson() {
    const name = nameInput.value.trim();
    if (!name) {
      showNotice("Type the new person's name first.");
      nameInput.focus();
      return;
    }
    if (!people.includes(name)) {
      added.add(name);
      people = [name, ...people];
    }
    chosenPerson = name;
    nameInput.value = '';
    showNotice('');
    setText(peopleStatus, '');
    show(peopleStatus, false);
    paintPeople();
  }
  addButton.addEventListener('click', addPerson);
  nameInput.addEventListener('keydown', (event) => {
    if (event.key === 'Enter') {
      event.preventDefault();
      addPerson();
    }
  });

  startButton.addEventListener('click', () => {
    // A name typed but not added yet is meant too.
    if (nameInput.value.trim()) addPerson();
    if (!chosenPerson) {
      showNotice('Choose who is eating, or add someone new.');
      return;
    }
    const person = chosenPerson;
    request('/api/meals', { user_id: person }).then((reply) => {
      // A new name the console refused (a bad id) leaves the list again.
      if (reply === null && added.has(person)) {
        added.delete(person);
        people = people.filter((p) => p !== person);
        if (chosenPerson === person) chosenPerson = '';
        paintPeople();
      }
    });
  });

  // --- the operator's question ----------------------------------------------
  const questionText = h('p', { className: 'question-text', id: 'question-text' });
  const yesButton = h('button', { type: 'button', className: 'answer yes', 'aria-pressed': 'false' }, 'Yes');
  const noButton = h('button', { type: 'button', className: 'answer no', 'aria-pressed': 'false' }, 'No');
  const answerNote = h('p', { className: 'answer-note' });
  const question = h(
    'section',
    { className: 'card question', 'aria-labelledby': 'question-heading', 'aria-describedby': 'question-text' },
    h('h2', { id: 'question-heading' }, 'Question for you'),
    questionText,
    h('div', { className: 'row answers', role: 'group', 'aria-labelledby': 'question-text' }, yesButton, noButton),
    answerNote,
  );
  function answer(success) {
    const bite = state?.current;
    if (!bite?.question || busy || !connected) return;
    request('/api/meal/answer', { event_id: bite.event_id, success });
  }
  yesButton.addEventListener('click', () => answer(true));
  noButton.addEventListener('click', () => answer(false));

  // --- the plate and the bite ----------------------------------------------
  const plate = createPlate({ onChoose: (index) => bite(index) });
  const choiceButton = h('button', { type: 'button', className: 'primary big', id: 'robots-choice' }, "Robot's choice");
  // After a failed look at the plate there is nothing to tap: look again.
  const lookButton = h(
    'button',
    { type: 'button', className: 'secondary big', id: 'look-again' },
    'Look at the plate again',
  );
  const plateCard = h(
    'section',
    { className: 'card plate-card', 'aria-labelledby': 'plate-heading' },
    h('h2', { id: 'plate-heading' }, 'The plate'),
    plate.root,
    choiceButton,
    lookButton,
  );
  lookButton.addEventListener('click', () => {
    if (state?.running && !busy && connected) request('/api/meal/look', {});
  });
  const bitePanel = createBitePanel();

  // Only a look that no bite has used yet: a bite may have taken or moved
  // the items, and a failed look leaves none.
  function canChoose() {
    if (!state?.running || busy || !connected || !(state.items?.length > 0)) return false;
    return state.plate_fresh === true && state.phase === 'choosing';
  }

  function bite(itemIndex) {
    if (!canChoose()) return;
    // The look the choice was made on: the console refuses it on another.
    request('/api/meal/bite', { item_index: itemIndex, plate_version: state.plate_version });
  }
  choiceButton.addEventListener('click', () => bite(-1));

  // --- summary and the end ------------------------------------------------------
  const summaryHeading = h('h2', { id: 'summary-heading', tabindex: '-1' }, 'This meal so far');
  const summaryText = h('p', { className: 'summary-text' });
  const foods = h('div', { className: 'foods' });
  const history = h('div', { className: 'history' });
  const endButton = h('button', { type: 'button', className: 'secondary', id: 'end-meal' }, 'End meal');
  const summary = h(
    'section',
    { className: 'card summary', 'aria-labelledby': 'summary-heading' },
    summaryHeading,
    summaryText,
    foods,
    history,
    endButton,
  );
  endButton.addEventListener('click', () => {
    if (state?.running && !busy && connected) request('/api/meal/end', {});
  });

  function paintSummary() {
    const sum = state.summary || {};
    const ended = !state.running;
    setText(summaryHeading, ended ? `Meal ${state.meal_id} is over` : 'This meal so far');
    setText(summaryText, sum.text || '');
    summary.dataset.attempts = String(sum.attempts ?? 0);
    summary.dataset.failures = String(sum.failures ?? 0);
    keyed(foods, JSON.stringify(sum.foods || []), () =>
      sum.foods?.length
        ? h(
            'table',
            { className: 'foods-table' },
            h('caption', {}, 'Per food'),
            h(
              'thead',
              {},
              h('tr', {}, ['Food', 'Attempts', 'Failures'].map((title) => h('th', { scope: 'col' }, title))),
            ),
            h(
              'tbody',
              {},
              sum.foods.map((f) =>
                h(
                  'tr',
                  { 'data-food': f.food, 'data-attempts': f.attempts, 'data-failures': f.failures },
                  h('th', { scope: 'row' }, f.food),
                  h('td', {}, f.attempts),
                  h('td', {}, f.failures),
                ),
              ),
            ),
          )
        : null,
    );
    const bites = state.bites || [];
    keyed(history, JSON.stringify(bites.map((b) => [b.number, b.text, b.outcome])), () =>
      bites.length
        ? [
            h('h3', {}, 'Bites'),
            h(
              'ol',
              { className: 'bite-list' },
              bites.map((b) => h('li', { 'data-outcome': b.outcome }, b.text || `Bite ${b.number}: ${b.outcome}`)),
            ),
          ]
        : null,
    );
    show(endButton, state.running);
    setAttr(endButton, 'aria-disabled', busy || !connected || isBiting() ? 'true' : null);
  }

  function isBiting() {
    return state?.phase === 'biting' && state.current?.outcome === 'pending';
  }

  // --- layout -------------------------------------------------------------------
  // The question comes first, so it is on top on a phone; on a tablet it
  // heads the column beside the plate.
  const mainColumn = h('div', { className: 'col col-main' }, plateCard);
  const sideColumn = h('div', { className: 'col col-side' }, bitePanel.root, summary);
  const meal = h('div', { className: 'meal-grid' }, question, mainColumn, sideColumn);
  const root = h(
    'section',
    { className: 'view table-view', 'aria-labelledby': 'table-heading' },
    top,
    meal,
    start,
  );

  // The summary sits beside the plate during a meal and above the start
  // form after it.
  function placeSummary(running) {
    const home = running ? sideColumn : root;
    if (summary.parentElement === home) return;
    const hadFocus = summary.contains(document.activeElement) || meal.contains(document.activeElement);
    if (running) sideColumn.append(summary);
    else root.insertBefore(summary, start);
    if (hadFocus) summaryHeading.focus();
  }

  function paint() {
    if (!state) {
      setText(heading, 'Meal');
      setText(mealLine, 'Waiting for the console…');
      show(meal, false);
      show(summary, false);
      show(start, false);
      return;
    }
    root.dataset.phase = state.phase;
    root.dataset.running = String(state.running);
    setText(heading, state.running ? `Meal ${state.meal_id}` : 'Meal');
    setText(
      mealLine,
      state.running
        ? `${state.user_id} is eating${state.bite > 0 ? `, ${count(state.bite, 'bite')} so far` : ''}.`
        : 'No meal is running.',
    );
    setText(message, state.message);
    // An error belongs to the running meal; once it is over the summary says what happened.
    const showError = Boolean(state.error) && (state.running || state.phase === 'failed');
    setText(error, showError ? state.error : '');

    placeSummary(state.running);
    show(meal, state.running);
    show(start, !state.running);
    show(summary, state.running || (state.bites?.length ?? 0) > 0);
    if (state.running) {
      const choose = canChoose();
      plate.update(state, choose);
      setAttr(choiceButton, 'aria-disabled', choose ? null : 'true');
      show(lookButton, state.phase === 'failed');
      setAttr(lookButton, 'aria-disabled', busy || !connected ? 'true' : null);

      const cur = state.current;
      const asking = Boolean(cur?.question);
      show(question, asking);
      if (asking) {
        setText(questionText, cur.question);
        setAttr(yesButton, 'aria-pressed', cur.answer === 'yes' ? 'true' : 'false');
        setAttr(noButton, 'aria-pressed', cur.answer === 'no' ? 'true' : 'false');
        setAttr(yesButton, 'aria-disabled', busy || !connected ? 'true' : null);
        setAttr(noButton, 'aria-disabled', busy || !connected ? 'true' : null);
        setText(
          answerNote,
          cur.answer
            ? `Your answer: ${cur.answer === 'yes' ? 'Yes' : 'No'}. You can change it until the next bite starts.`
            : 'Answer Yes or No. The robot learns from your answer.',
        );
      }
      bitePanel.update(cur);
    }
    paintSummary();
  }

  let lastRunning = null;
  let lastBiteNumber = null;
  function setState(next) {
    const number = int(next.current?.number);
    if (lastBiteNumber !== null && number > lastBiteNumber) document.dispatchEvent(new Event(BITE_STARTED));
    lastBiteNumber = number;
    state = next;
    root.dataset.bite = String(int(state.bite));
    // When a meal ends, the list of people may have grown by its person.
    if (lastRunning !== state.running && !state.running) loadPeople();
    lastRunning = state.running;
    paint();
  }

  function setConnection(status) {
    connection.dataset.connection = status;
    root.dataset.connection = status;
    setText(
      connection,
      {
        live: 'Live',
        connecting: 'Connecting…',
        lost: 'Connection lost: retrying… What is shown may be out of date, and the arm may be moving.',
      }[status],
    );
    connected = status === 'live';
    paint();
  }

  let opened = false;
  function open() {
    if (opened) return;
    opened = true;
    paint();
    openMealStream({
      onState: setState,
      onProgress: (event) => {
        if (state?.running) bitePanel.progress(event);
      },
      onConnection: setConnection,
    });
  }

  return { root, heading, open };
}
