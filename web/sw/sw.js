/* The site's service worker (dist/sw.js, written from this template by
 * scripts/precompress.mjs, which fills in the version and the shell list; pages register it
 * after their first frame with `registerOfflineCache()`). Repeat visits load from Cache Storage
 * and the site works offline after the first visit:
 *
 * - install: the shell (every page, script and style of the build, a few MB before compression)
 *   goes into `mm-shell-<version>`; the version is a hash over the content of every built file,
 *   so any change installs a new worker, and activation deletes the caches of the builds before
 *   the one it replaces;
 * - pages (navigations): from the shell — a page changes only with a build, and every build is a
 *   new worker with a new shell — so a returning visitor's page waits for no network round trip;
 *   a page the shell lacks (a query string, say): network first, a cached copy when it fails;
 * - content-hashed files (`assets/name-HASH.ext`, onnxruntime's module…): cache first, stored
 *   on first use;
 * - the library's versioned assets (`?v=<hash>`: WASM core, database, avatar, model) are cached
 *   by the library itself in `mm-avatar-assets` (web/src/cache.ts, which also works in pages
 *   without this worker); this worker serves them from there too;
 * - anything else of this origin: network first, falling back to any cached copy;
 * - where the browser has static routes (`InstallEvent.addRoutes`), the pages, the shell's scripts
 *   and styles and the versioned assets skip the fetch handler: the browser reads Cache Storage;
 * - activation keeps the build before this one (its shell and runtime cache): a page it served
 *   just now may load its lazy chunks (the rooms' code, three-vrm…) after this worker takes over.
 */
const VERSION = self.__MM_VERSION__;
const SHELL = self.__MM_SHELL__;
const SHELL_CACHE = `mm-shell-${VERSION}`;
const RUNTIME_CACHE = `mm-runtime-${VERSION}`;
// Which build was current before this one (activate): its caches stay until the next build.
const META_CACHE = 'mm-sw-meta';
const CURRENT_KEY = '/__mm-sw/current-version';
// Matches ignore `Vary: Accept-Encoding` (the server's precompressed files): a cache holds
// decoded bodies, so the encoding a response was sent with does not matter to a match.
const MATCH = { ignoreVary: true };
const HASHED = /\/assets\/[^/]+-[A-Za-z0-9_-]{8}\.[a-z0-9]+$/;

self.addEventListener('install', (event) => {
  // Static routes (where the browser has them): the shell's scripts and styles and the library's
  // versioned assets are answered from Cache Storage by the browser itself, without running this
  // worker's fetch handler — a returning visitor's modules arrived ~30-45 ms sooner here. A miss
  // goes to the network (the library stores its assets itself; the shell is stored below).
  // What no route names (pages, the runtime cache's files) comes through the fetch handler.
  if (event.addRoutes && typeof URLPattern !== 'undefined') {
    const scope = new URL(self.registration.scope);
    const here = { protocol: scope.protocol.slice(0, -1), hostname: scope.hostname, port: scope.port };
    const shellFiles = { or: ['js', 'css'].map((ext) => ({ urlPattern: new URLPattern({ ...here, pathname: `${scope.pathname}assets/*.${ext}` }) })) };
    const versioned = { urlPattern: new URLPattern({ ...here, pathname: `${scope.pathname}*`, search: 'v=*' }) };
    const pages = { requestMode: 'navigate', urlPattern: new URLPattern({ ...here, pathname: `${scope.pathname}*` }) };
    event.addRoutes([
      { condition: shellFiles, source: 'cache' },
      { condition: versioned, source: 'cache' },
      { condition: pages, source: { cacheName: SHELL_CACHE } }, // this build's pages only
    ]).catch(() => undefined); // a browser that refuses them: the fetch handler answers as before
  }
  event.waitUntil(
    (async () => {
      const cache = await caches.open(SHELL_CACHE);
      // One by one, each tried three times: a file that still fails (a 404 in a hand-edited
      // dist/) does not block the rest, and a busy server's dropped request is tried again
      // (a shell file missing here is a page that cannot start offline).
      await Promise.all(
        SHELL.map(async (url) => {
          for (let attempt = 1; attempt <= 3; attempt++) {
            try {
              return await cache.add(new Request(url, { cache: 'no-cache' }));
            } catch {
              await new Promise((resolve) => setTimeout(resolve, 250 * attempt));
            }
          }
        }),
      );
      await self.skipWaiting();
    })(),
  );
});

self.addEventListener('activate', (event) => {
  event.waitUntil(
    (async () => {
      const meta = await caches.open(META_CACHE);
      const previous = await (await meta.match(CURRENT_KEY))?.text();
      const keep = new Set([VERSION, previous]);
      for (const name of await caches.keys()) {
        const build = /^mm-(?:shell|runtime)-(.+)$/.exec(name)?.[1];
        if (build !== undefined && !keep.has(build)) await caches.delete(name);
      }
      if (previous !== VERSION) await meta.put(CURRENT_KEY, new Response(VERSION));
      await self.clients.claim();
    })(),
  );
});

async function networkFirst(request, store) {
  try {
    const response = await fetch(request);
    if (response.ok && response.status === 200 && store) {
      const copy = response.clone();
      caches.open(store).then((c) => c.put(request, copy)).catch(() => undefined);
    }
    return response;
  } catch (e) {
    const hit = (await caches.match(request, MATCH)) ?? (await caches.match(request, { ...MATCH, ignoreSearch: true }));
    if (hit) return hit;
    if (request.mode === 'navigate') {
      const shell = await caches.match(new URL('./', self.registration.scope).href, MATCH);
      if (shell) return shell;
    }
    throw e;
  }
}

/** A page from this build's shell, else the network first (a page the shell lacks). */
async function fromShell(request) {
  const hit = await (await caches.open(SHELL_CACHE)).match(request, MATCH);
  return hit ?? networkFirst(request, SHELL_CACHE);
}

async function cacheFirst(request) {
  const hit = await caches.match(request, MATCH);
  if (hit) return hit;
  const response = await fetch(request);
  if (response.ok && response.status === 200) {
    const copy = response.clone();
    caches.open(RUNTIME_CACHE).then((c) => c.put(request, copy)).catch(() => undefined);
  }
  return response;
}

self.addEventListener('fetch', (event) => {
  const request = event.request;
  if (request.method !== 'GET' || request.headers.has('range')) return;
  const url = new URL(request.url);
  if (url.origin !== self.location.origin || url.pathname.startsWith('/rooms')) return;
  if (request.mode === 'navigate') event.respondWith(fromShell(request));
  else if (HASHED.test(url.pathname)) event.respondWith(cacheFirst(request));
  else if (url.searchParams.has('v')) event.respondWith(caches.match(request, MATCH).then((hit) => hit ?? fetch(request)));
  else event.respondWith(networkFirst(request, SHELL.includes(url.pathname.replace(/^\//, '')) ? SHELL_CACHE : null));
});
