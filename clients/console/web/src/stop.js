// STOP: on every screen, wired before anything else loads. One POST per
// press: a pointer press sends on pointerdown (no waiting for the release),
// and the click that follows the same press is ignored; keyboard presses
// (Enter, Space) have no pointerdown and send on click.

import { postJSON } from './api.js';

// With no reply this long, the page tells the person to use the robot's own
// emergency stop (the request stays open, and its reply still shows).
export const STOP_NO_REPLY_MS = 2000;

// Dispatched on `document` by the table view when a new bite starts.
export const BITE_STARTED = 'bitewise:bite-started';
const IDLE_TEXT = 'Stops the arm at once.';

export function initStop(button, status) {
  let pressSent = false; // this pointer press already sent its POST
  let latest = 0; // the newest press owns the status line

  // `started`: the input event's time (same clock as performance.now()), so
  // any wait before this handler ran counts too.
  async function stop(started) {
    const press = ++latest;
    button.setAttribute('aria-busy', 'true');
    status.className = 'stop-status sending';
    status.textContent = 'Stopping…';
    delete status.dataset.wasMoving;
    const noReply = setTimeout(() => {
      if (press !== latest) return;
      status.className = 'stop-status failed';
      status.textContent =
        `No reply to STOP after ${STOP_NO_REPLY_MS / 1000} s: use the robot's own emergency stop. ` +
        '(Still waiting for the console.)';
    }, STOP_NO_REPLY_MS);
    try {
      // High priority, and keepalive: the request goes out even if the page is
      // being closed or reloaded at that moment.
      const reply = await postJSON('/api/stop', {}, { priority: 'high', keepalive: true });
      const ms = performance.now() - started;
      // Read by the browser tests: click-to-reply time as the page saw it.
      document.body.dataset.stopReplyMs = ms.toFixed(1);
      // The console's own part of it (request in to the robot's reply).
      if (Number.isFinite(reply?.reply_ms)) document.body.dataset.stopServerMs = reply.reply_ms.toFixed(1);
      if (press !== latest) return;
      const moving = Boolean(reply?.was_moving);
      status.className = 'stop-status stopped';
      status.dataset.wasMoving = String(moving);
      status.textContent =
        `Stopped: the arm ${moving ? 'was moving and was halted' : 'was not moving'}` +
        ` at ${new Date().toLocaleTimeString()} (reply in ${Math.round(ms)} ms).`;
    } catch (err) {
      if (press !== latest) return;
      status.className = 'stop-status failed';
      status.textContent = `STOP did not go through: ${err.message}. Use the robot's own emergency stop.`;
    } finally {
      clearTimeout(noReply);
      if (press === latest) button.removeAttribute('aria-busy');
    }
  }

  // A new bite moves the arm again: a line saying it was halted is history.
  document.addEventListener(BITE_STARTED, () => {
    if (status.className !== 'stop-status stopped') return;
    status.className = 'stop-status';
    status.textContent = IDLE_TEXT;
    delete status.dataset.wasMoving;
  });

  button.addEventListener('pointerdown', (event) => {
    if (event.button !== 0) return; // primary button, touch or pen contact
    pressSent = true;
    stop(event.timeStamp || performance.now());
  });
  button.addEventListener('click', (event) => {
    // detail is 0 for keyboard and programmatic clicks, which have no pointerdown.
    if (event.detail !== 0 && pressSent) {
      pressSent = false;
      return;
    }
    pressSent = false;
    stop(event.timeStamp || performance.now());
  });
}
