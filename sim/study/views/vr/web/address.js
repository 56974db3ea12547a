// The launch's key leaves the page's address once the page has used it. The server prints the address with the key
// (?key=..., sim/study/views/vr/access.py) and, as it serves the page, keeps the key in a cookie (HttpOnly) that the
// page's own requests carry. Once one of them has been answered, the cookie is known to work and the key has no use
// in the address, where it would stay in the tab's history, the address bar, a bookmark or a screenshot of the page;
// a reload or a bookmark of the address without it is served by the cookie. (The browser's own list of visited
// addresses may still hold the address as first opened: the key is new at each launch of the server.)

// `href` without the query parameter `parameter` (the rest of the address as it was).
export function withoutKey(href, parameter) {
  const url = new URL(href);
  url.searchParams.delete(parameter);
  return url.href;
}

// Replace the tab's current address with the one without the key: no reload and no new history entry.
export function forgetKey(location, history, parameter) {
  const keyless = withoutKey(location.href, parameter);
  if (keyless !== location.href) history.replaceState(history.state, '', keyless);
}
