/**
 * The benchmark page (bench.html): times the three searches in this browser's WASM on the
 * databases named by `?db=` and, with `?runtime=<database>`, the character update and crowd;
 * shows a table. `scripts/bench.mjs` drives it in headless Chromium and reads
 * `window.__searchBench`. Only the library's public entry and the pages' kit are used.
 */
import { initWasm } from '../../index.ts';
import {
  type RuntimeBenchResult, type SearchBenchResult, benchRuntime, benchSearch, catchPageErrors, errorMessage, fetchBytes,
} from '../kit.ts';

const hook = {
  done: false,
  error: null as string | null,
  /** Whether `performance.now()` has 5 µs resolution (cross-origin isolated) rather than 100 µs. */
  crossOriginIsolated,
  userAgent: navigator.userAgent,
  results: [] as SearchBenchResult[],
  runtime: null as RuntimeBenchResult | null,
};
declare global {
  interface Window {
    __searchBench: typeof hook;
  }
}
window.__searchBench = hook;

const status = document.getElementById('status')!;

const fail = catchPageErrors(hook, () => {
  const box = document.getElementById('error-box')!;
  box.textContent = hook.error;
  box.hidden = false;
  status.textContent = 'failed';
  hook.done = true;
});

function show(r: SearchBenchResult): void {
  const table = document.getElementById('results') as HTMLTableElement;
  table.hidden = false;
  for (const m of r.methods) {
    const row = table.tBodies[0].insertRow();
    const times = [m.median_ms.toFixed(4), m.p95_ms.toFixed(4), m.mean_ms.toFixed(4), r.index_build_ms.toFixed(2)];
    for (const text of [r.database, String(r.frames), m.method, ...times]) row.insertCell().textContent = text;
  }
}

/**
 * `?db=` entries: a name in databases/, or a path from the site root (the bench's pinned recipes,
 * bench-databases/x.mmdb, named x).
 */
const databaseUrl = (entry: string): [string, string] =>
  entry.includes('/')
    ? [`/${entry.replace(/^\//, '')}`, entry.replace(/^.*\//, '').replace(/\.mmdb$/, '')]
    : [`databases/${entry}`, entry];

/** Yields so the page paints between databases. */
const nextFrame = (): Promise<void> => new Promise((resolve) => setTimeout(resolve, 0));

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const queries = Number(params.get('queries') ?? 400);
  await initWasm();
  for (const file of (params.get('db') ?? 'locomotion.mmdb').split(',').filter(Boolean)) {
    const [url, name] = databaseUrl(file);
    status.textContent = `loading ${name}…`;
    const bytes = await fetchBytes(url, { stage: 'database' });
    status.textContent = `benchmarking ${name}…`;
    await nextFrame();
    const result = benchSearch(name, bytes, { queries });
    hook.results.push(result);
    show(result);
    if (result.mismatches > 0) fail(`${name}: the three methods disagreed on ${result.mismatches} queries`);
  }
  const runtime = params.get('runtime');
  if (runtime) {
    status.textContent = `character updates on ${runtime}…`;
    await nextFrame();
    const [url, name] = databaseUrl(runtime);
    hook.runtime = benchRuntime(name, await fetchBytes(url, { stage: 'database' }));
  }
  status.textContent = `done (${crossOriginIsolated ? '5 µs' : '100 µs'} timer resolution)`;
  hook.done = true;
}

main().catch((e: unknown) => fail(errorMessage(e)));
