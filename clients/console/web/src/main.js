// bitewise-console's page: STOP first, then the session and the two views,
// chosen by the hash: #/table (the default) and #/research.

import 'uplot/dist/uPlot.min.css';
import './styles.css';

import { getJSON } from './api.js';
import { setAttr, setText, show } from './dom.js';
import { createResearchView } from './research-view.js';
import { initStop } from './stop.js';
import { createTableView } from './table-view.js';

// STOP first: it works before any data has loaded, whatever fails after.
initStop(document.getElementById('stop-button'), document.getElementById('stop-status'));

const main = document.getElementById('main');
const navLinks = [...document.querySelectorAll('nav a[data-view]')];
const views = {};

function view(name) {
  if (!views[name]) {
    views[name] = name === 'research' ? createResearchView() : createTableView();
    views[name].root.hidden = true;
    main.append(views[name].root);
  }
  return views[name];
}

/** "#/research?user=alice" -> {name: 'research', params}. */
function parseHash() {
  const [path, search = ''] = location.hash.replace(/^#/, '').split('?');
  const name = path.replace(/^\/+/, '').split('/')[0] === 'research' ? 'research' : 'table';
  return { name, params: new URLSearchParams(search) };
}

let current = '';
function route(moved) {
  const { name, params } = parseHash();
  const switched = name !== current;
  current = name;
  for (const [key, v] of Object.entries(views)) show(v.root, key === name);
  const target = view(name);
  show(target.root, true);
  document.body.dataset.view = name;
  document.title = `${name === 'research' ? 'Research' : 'Table'} · bitewise console`;
  for (const link of navLinks) setAttr(link, 'aria-current', link.dataset.view === name ? 'page' : null);
  if (name === 'table') target.open();
  else target.show(params, { moved: moved && !switched, entered: switched });
  // Take the keyboard and screen readers to the new view, but not on load.
  if (moved && switched) target.heading.focus();
}

window.addEventListener('hashchange', () => route(true));
route(false);

// Who is using the console (role decides what the console allows).
getJSON('/api/session')
  .then((session) => {
    const who = document.getElementById('session');
    const role = session?.role || '';
    setText(who, role === 'local' ? 'On this computer' : `${session?.name || 'Signed in'} (${role})`);
    document.body.dataset.role = role;
    // Caregivers cannot open the researcher view: do not offer it.
    const research = navLinks.find((a) => a.dataset.view === 'research');
    if (research) show(research.parentElement, role !== 'caregiver');
  })
  .catch(() => {});
