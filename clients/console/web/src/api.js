// The console's HTTP API (docs/console.md). Every call stays on the page's
// own origin; errors come back as {"error": "..."} and are thrown as
// ApiError carrying that sentence, so views can show it as it is.

export class ApiError extends Error {
  constructor(message, status) {
    super(message);
    this.name = 'ApiError';
    this.status = status;
  }
}

async function readReply(response, what) {
  let body = null;
  const text = await response.text();
  if (text) {
    try {
      body = JSON.parse(text);
    } catch {
      body = null;
    }
  }
  if (!response.ok) {
    const message =
      body && typeof body.error === 'string' && body.error
        ? body.error
        : `${what} failed: HTTP ${response.status} ${response.statusText}`.trim();
    throw new ApiError(message, response.status);
  }
  if (body && typeof body.error === 'string' && body.error) {
    throw new ApiError(body.error, response.status);
  }
  return body;
}

async function send(method, path, body, extra) {
  const init = { method, cache: 'no-store', credentials: 'same-origin', headers: {}, ...extra };
  if (method !== 'GET') {
    // The console refuses state changes without this header (CSRF guard).
    init.headers['X-Bitewise-Request'] = '1';
    init.headers['Content-Type'] = 'application/json';
    init.body = JSON.stringify(body ?? {});
  }
  let response;
  try {
    response = await fetch(path, init);
  } catch (err) {
    throw new ApiError(`The console did not answer (${method} ${path}): ${err.message}`, 0);
  }
  return readReply(response, `${method} ${path}`);
}

export const getJSON = (path) => send('GET', path);
/** `extra`: more fetch options (STOP asks for high priority). */
export const postJSON = (path, body, extra) => send('POST', path, body, extra);

/** Path segment for a user id (ids may hold characters a URL reserves). */
export const userPath = (user) => `/api/people/${encodeURIComponent(user)}`;

/** Builds a query string from the non-empty values of `params`. */
export function query(params) {
  const search = new URLSearchParams();
  for (const [key, value] of Object.entries(params)) {
    if (value !== undefined && value !== null && value !== '') search.set(key, String(value));
  }
  const text = search.toString();
  return text ? `?${text}` : '';
}
