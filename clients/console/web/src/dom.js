// A few DOM helpers instead of a framework. Views build their skeleton once
// and then update text and attributes in place, so a live update never takes
// the keyboard focus away from what the person was about to press.

const SVG_NS = 'http://www.w3.org/2000/svg';

function apply(el, attrs) {
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith('on') && typeof value === 'function') {
      el.addEventListener(key.slice(2), value);
    } else if (key === 'dataset') {
      Object.assign(el.dataset, value);
    } else if (key === 'className') {
      el.setAttribute('class', value);
    } else {
      // Never a style attribute: the console may forbid inline styles (CSP).
      el.setAttribute(key, value === true ? '' : String(value));
    }
  }
  return el;
}

function append(el, children) {
  for (const child of children.flat(Infinity)) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : String(child));
  }
  return el;
}

/** h('button', {type: 'button', onclick}, 'text', ...) */
export function h(tag, attrs, ...children) {
  return append(apply(document.createElement(tag), attrs), children);
}

/** The same for SVG elements. */
export function s(tag, attrs, ...children) {
  return append(apply(document.createElementNS(SVG_NS, tag), attrs), children);
}

/** Sets the text only when it changed (keeps screen readers quiet). */
export function setText(el, text) {
  const value = text ?? '';
  if (el.textContent !== value) el.textContent = value;
}

/** Sets or removes an attribute; null/undefined/false removes it. */
export function setAttr(el, name, value) {
  if (value === null || value === undefined || value === false) {
    if (el.hasAttribute(name)) el.removeAttribute(name);
    return;
  }
  const text = value === true ? '' : String(value);
  if (el.getAttribute(name) !== text) el.setAttribute(name, text);
}

export function show(el, visible) {
  if (el.hidden === visible) el.hidden = !visible;
}

/**
 * Rebuilds `container`'s children with build() only when `key` changed since
 * the last call. If the focus was on a child carrying data-focus-key, the
 * rebuilt child with the same data-focus-key gets it back, without scrolling.
 */
export function keyed(container, key, build) {
  if (container.__key === key) return false;
  container.__key = key;
  const active = document.activeElement;
  const focusKey =
    active && container.contains(active) ? active.closest('[data-focus-key]')?.dataset.focusKey : undefined;
  container.replaceChildren(...[build()].flat(Infinity).filter(Boolean));
  if (focusKey !== undefined) {
    // The child is where its predecessor was; scrolling to it would pull the
    // page away from whatever the person is reading (a question, the bite).
    container.querySelector(`[data-focus-key="${CSS.escape(focusKey)}"]`)?.focus({ preventScroll: true });
  }
  return true;
}
