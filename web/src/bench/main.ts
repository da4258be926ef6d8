/**
 * The search benchmark page (`web/bench.html`): times the three searches in this browser's
 * WASM on the databases named by `?db=` and shows a table. `scripts/bench.mjs` drives it in
 * headless Chromium and reads `window.__searchBench`.
 */
import { RawCrowd, RawDatabase, RawSearchIndex } from '../core/pkg/mmcore.js';
import { initWasm } from '../core/wasm.ts';
import { benchRuntime, type RuntimeBenchResult } from './runtime-bench.ts';
import { benchSearch, type SearchBenchResult } from './search-bench.ts';

/** `window.__searchBench`: progress and results for the driver script. */
export interface SearchBenchHook {
  done: boolean;
  error: string | null;
  /** Whether `performance.now()` has 5 µs resolution (cross-origin isolated) rather than 100 µs. */
  crossOriginIsolated: boolean;
  userAgent: string;
  results: SearchBenchResult[];
  /** The character-update benchmark, when `?runtime=<database>` asks for it. */
  runtime: RuntimeBenchResult | null;
}

declare global {
  interface Window {
    __searchBench: SearchBenchHook;
  }
}

const hook: SearchBenchHook = { done: false, error: null, crossOriginIsolated, userAgent: navigator.userAgent, results: [], runtime: null };
window.__searchBench = hook;

const status = document.getElementById('status') as HTMLElement;

function fail(message: string): void {
  hook.error = hook.error ? `${hook.error}\n${message}` : message;
  const box = document.getElementById('error-box') as HTMLElement;
  box.textContent = hook.error;
  box.hidden = false;
  status.textContent = 'failed';
  hook.done = true;
}

function showResult(r: SearchBenchResult): void {
  const table = document.getElementById('results') as HTMLTableElement;
  table.hidden = false;
  for (const m of r.methods) {
    const row = table.tBodies[0].insertRow();
    const cells = [r.database, String(r.frames), m.method, m.median_ms.toFixed(4), m.p95_ms.toFixed(4), m.mean_ms.toFixed(4), r.index_build_ms.toFixed(2)];
    for (const text of cells) row.insertCell().textContent = text;
  }
}

/** Yields to the event loop so the page paints between databases. */
const nextFrame = (): Promise<void> => new Promise((resolve) => setTimeout(resolve, 0));

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const names = (params.get('db') ?? 'locomotion.mmdb').split(',').filter(Boolean);
  const queries = Number(params.get('queries') ?? 400);
  const exports = await initWasm();
  for (const name of names) {
    status.textContent = `loading ${name}…`;
    await nextFrame();
    const response = await fetch(`/databases/${name}`);
    if (!response.ok) throw new Error(`/databases/${name}: HTTP ${response.status}`);
    const bytes = new Uint8Array(await response.arrayBuffer());
    status.textContent = `benchmarking ${name}…`;
    await nextFrame();
    const result = benchSearch({ RawDatabase, RawSearchIndex, memory: exports.memory }, name, bytes, { queries });
    hook.results.push(result);
    showResult(result);
    if (result.mismatches > 0) fail(`${name}: the three methods disagreed on ${result.mismatches} queries`);
  }
  const runtimeDb = params.get('runtime');
  if (runtimeDb) {
    status.textContent = `character updates on ${runtimeDb}…`;
    await nextFrame();
    const response = await fetch(`/databases/${runtimeDb}`);
    if (!response.ok) throw new Error(`/databases/${runtimeDb}: HTTP ${response.status}`);
    hook.runtime = benchRuntime(RawCrowd, runtimeDb, new Uint8Array(await response.arrayBuffer()));
  }
  status.textContent = `done (${crossOriginIsolated ? '5 µs' : '100 µs'} timer resolution)`;
  hook.done = true;
}

window.addEventListener('error', (e) => fail(`error: ${e.message}`));
window.addEventListener('unhandledrejection', (e) => fail(`error: ${e.reason instanceof Error ? e.reason.message : String(e.reason)}`));
main().catch((e: unknown) => fail(e instanceof Error ? e.message : String(e)));
