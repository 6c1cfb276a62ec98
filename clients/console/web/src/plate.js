// The plate: the camera's last frame with the detected items drawn over it.
// The overlay's viewBox is the frame's pixel size, so the items' bounding
// boxes (frame pixels) land on the picture at any screen width.

import { h, keyed, s, setAttr, setText, show } from './dom.js';
import { count, itemName } from './format.js';

// Each item's touch target is at least this fraction of the frame's width
// (about 44 CSS pixels on a 360-pixel phone), centred on the item.
const MIN_TARGET = 0.13;

export function createPlate({ onChoose }) {
  const img = h('img', { className: 'plate-img', alt: 'The plate as the camera last saw it', decoding: 'async' });
  const overlay = s('svg', {
    className: 'plate-overlay',
    preserveAspectRatio: 'none',
    role: 'group',
    'aria-label': 'Items on the plate',
  });
  const empty = h('p', { className: 'plate-empty' }, 'No picture of the plate yet.');
  const frame = h('div', { className: 'plate-frame' }, img, overlay, empty);
  const caption = h('figcaption', { className: 'plate-caption' });
  const root = h('figure', { className: 'plate' }, frame, caption);

  let enabled = false;
  let picture = ''; // the meal and plate_version on show

  img.addEventListener('load', () => {
    show(img, true);
    show(empty, false);
  });
  img.addEventListener('error', () => {
    // 404 until the console has looked at the plate once.
    show(img, false);
    show(empty, true);
  });
  show(img, false);

  function choose(target) {
    const item = target.closest('[data-item-index]');
    if (!item || !enabled) return;
    onChoose(Number(item.dataset.itemIndex));
  }
  overlay.addEventListener('click', (event) => choose(event.target));
  overlay.addEventListener('keydown', (event) => {
    if (event.key !== 'Enter' && event.key !== ' ') return;
    event.preventDefault(); // Space would scroll the page
    choose(event.target);
  });

  function drawItems(items, width, height, currentIndex) {
    const minSide = MIN_TARGET * width;
    const fontSize = Math.max(14, width / 22);
    return items.map((item, index) => {
      const { x, y, width: w, height: hh } = item.bbox;
      const cx = x + w / 2;
      const cy = y + hh / 2;
      const tw = Math.max(w, minSide);
      const th = Math.max(hh, minSide);
      const badgeX = Math.max(fontSize * 0.8, Math.min(width - fontSize * 0.8, x));
      const badgeY = Math.max(fontSize * 0.8, Math.min(height - fontSize * 0.8, y));
      const classes = ['item'];
      if (index === currentIndex) classes.push('current');
      return s(
        'g',
        {
          className: classes.join(' '),
          role: 'button',
          tabindex: enabled ? '0' : '-1',
          'aria-disabled': enabled ? 'false' : 'true',
          'aria-label': itemName(index, item, width, height) + (index === currentIndex ? ', the last bite' : ''),
          'data-item-index': index,
          'data-focus-key': `item-${index}`,
        },
        s('rect', { className: 'hit', x: cx - tw / 2, y: cy - th / 2, width: tw, height: th }),
        s('rect', { className: 'box', x, y, width: w, height: hh, rx: fontSize / 4 }),
        s('circle', { className: 'badge', cx: badgeX, cy: badgeY, r: fontSize * 0.75 }),
        s('text', { className: 'badge-text', x: badgeX, y: badgeY, 'font-size': fontSize, dy: '0.35em' }, index + 1),
      );
    });
  }

  /** Shows `state` (a MealState); `canChoose` says whether a tap starts a bite. */
  function update(state, canChoose) {
    const width = state.frame_width || 0;
    const height = state.frame_height || 0;
    const items = state.items || [];
    enabled = canChoose;
    // plate_version starts again at 1 in every meal: the meal is part of the key.
    const next = `v=${state.plate_version}&meal=${encodeURIComponent(state.meal_id)}`;
    if (state.plate_version > 0 && next !== picture) {
      picture = next;
      img.src = `/api/meal/plate.jpg?${next}`;
    }
    if (width > 0 && height > 0) {
      setAttr(overlay, 'viewBox', `0 0 ${width} ${height}`);
      // Reserve the picture's shape before it loads (CSSOM, not a style attribute).
      frame.style.aspectRatio = `${width} / ${height}`;
      frame.style.setProperty('--aspect', String(width / height));
    }
    // The bite's item, while it runs: once the plate is looked at again the
    // items are numbered anew and the old index means another item.
    const current = state.phase === 'biting' && state.current?.number > 0 ? state.current.item_index : -1;
    const key = JSON.stringify([picture, width, height, enabled, current, items.map((i) => i.bbox)]);
    keyed(overlay, key, () => (width > 0 && height > 0 ? drawItems(items, width, height, current) : []));
    setAttr(overlay, 'aria-label', `Items on the plate: ${count(items.length, 'item')}`);
    setText(
      caption,
      state.phase === 'looking'
        ? 'Looking at the plate…'
        : items.length === 0
          ? 'No food detected.'
          : canChoose
            ? `${count(items.length, 'item')} on the plate. Tap one to eat it next, or let the robot choose.`
            : state.running && !state.plate_fresh && state.phase === 'failed'
              ? // A bite since may have taken or moved them.
                `${count(items.length, 'item')} seen before bite ${state.bite}; look at the plate again to choose.`
              : `${count(items.length, 'item')} on the plate.`,
    );
  }

  return { root, update };
}
