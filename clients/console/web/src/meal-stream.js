// The live meal: Server-Sent Events from /api/meal/stream. `state` carries the
// whole MealState (sent at once on every connection, so a reconnect repaints
// everything); `progress` carries one Acquire report (BiteEvent); `ping`
// comes every 2 s when nothing else does. The page is 'live' only while it
// hears from the console: after STALE_MS of silence it says the connection
// is lost and opens a new stream.

const RETRY_MS = 2000;
// The console sends a `ping` every 2 s when nothing else happens. A stream
// silent this long has died without an error (Wi-Fi gone, a NAT that forgot
// it, a hung console): what the page shows is no longer the meal.
export const STALE_MS = 6000;
const MAX_LATENCIES = 10000;

// Paint latencies of progress events, in seconds: the page's wall clock when
// the frame showing the report is produced, minus the console's clock when it
// got the report from the robot. A benchmark reads this array.
window.__progressLatencies = window.__progressLatencies || [];

function recordPaintLatency(wallTimeS) {
  if (!(wallTimeS > 0)) return;
  requestAnimationFrame(() => {
    // timeOrigin + now(): a wall clock with sub-millisecond resolution.
    const nowS = (performance.timeOrigin + performance.now()) / 1000;
    const latencies = window.__progressLatencies;
    latencies.push(nowS - wallTimeS);
    if (latencies.length > MAX_LATENCIES) latencies.splice(0, latencies.length - MAX_LATENCIES);
  });
}

/**
 * Opens the stream and keeps it open. Callbacks: onState(MealState),
 * onProgress(BiteEvent) and onConnection('live' | 'connecting' | 'lost').
 * Returns a function that closes it.
 */
export function openMealStream({ onState, onProgress, onConnection }) {
  let source = null;
  let retry = 0;
  let closed = false;

  function parse(event) {
    try {
      return JSON.parse(event.data);
    } catch {
      return null;
    }
  }

  let lastHeard = 0; // performance.now() of the newest event
  let status = '';
  function say(next) {
    if (next === status) return;
    status = next;
    onConnection(next);
  }
  function heard() {
    lastHeard = performance.now();
    say('live');
  }
  // Whatever the status: a stream (first, reconnecting or new) that says
  // nothing for STALE_MS is closed and opened again, and the page says the
  // connection is lost until one is heard.
  const watchdog = setInterval(() => {
    if (closed || performance.now() - lastHeard < STALE_MS) return;
    say('lost');
    clearTimeout(retry);
    source?.close();
    connect(); // a new stream starts with the whole state
  }, 1000);

  function connect() {
    if (status === '') say('connecting');
    lastHeard = performance.now(); // the new stream's time starts now
    source = new EventSource('/api/meal/stream');
    source.addEventListener('ping', heard);
    source.addEventListener('state', (event) => {
      heard();
      const state = parse(event);
      if (state) onState(state);
    });
    source.addEventListener('progress', (event) => {
      heard();
      const progress = parse(event);
      if (!progress) return;
      onProgress(progress);
      recordPaintLatency(Number(progress.wall_time_s));
    });
    source.addEventListener('error', () => {
      // EventSource retries by itself unless the reply was not a stream
      // (an HTTP error, the console restarting): then it is CLOSED and we
      // retry ourselves.
      if (source.readyState === EventSource.CLOSED && !closed) {
        say('lost');
        retry = setTimeout(connect, RETRY_MS);
      } else if (status !== 'lost') {
        say('connecting');
      }
    });
  }

  connect();
  return () => {
    closed = true;
    clearInterval(watchdog);
    clearTimeout(retry);
    source?.close();
  };
}
