// The live meal: Server-Sent Events from /api/meal/stream. `state` carries the
// whole MealState (sent at once on every connection, so a reconnect repaints
// everything); `progress` carries one Acquire report (BiteEvent).

const RETRY_MS = 2000;
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

  function connect() {
    onConnection('connecting');
    source = new EventSource('/api/meal/stream');
    source.addEventListener('open', () => onConnection('live'));
    source.addEventListener('state', (event) => {
      const state = parse(event);
      if (state) onState(state);
    });
    source.addEventListener('progress', (event) => {
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
        onConnection('lost');
        retry = setTimeout(connect, RETRY_MS);
      } else {
        onConnection('connecting');
      }
    });
  }

  connect();
  return () => {
    closed = true;
    clearTimeout(retry);
    source?.close();
  };
}
