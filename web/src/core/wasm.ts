/**
 * Loads the WASM module once and exposes its linear memory. Many characters and databases
 * share this one module.
 *
 * Browser: `initWasm(url?)` fetches the module from `url`, default `mmcore_bg.wasm` beside the
 * library's assets (see `assets.ts`). Node (vitest, scripts): `initWasm()` reads the built file
 * from disk, or call `initWasmSync(bytes)`.
 */
import { initWasmModule, initWasmModuleSync, live_objects } from './raw.ts';
import { PACKAGE, assetUrl } from '../assets.ts';
import { type FetchOptions, type FetchProgress, fetchBytes, mark } from '../fetch.ts';

/** What the module's initializer returns: its exports, including `memory`. */
export interface WasmExports {
  readonly memory: WebAssembly.Memory;
}

let _exports: WasmExports | null = null;
let _pending: Promise<WasmExports> | null = null;
/** Everyone waiting on the pending load who wants its progress. */
const _listeners = new Set<(p: FetchProgress) => void>();

/** Node (tests, tools, server-side rendering) rather than a browser: read the module from disk
 * there. Asked when loading, never at import (importing touches no browser global). */
const isNode = () => typeof (globalThis as { process?: { versions?: { node?: string } } }).process?.versions?.node === 'string' && typeof window === 'undefined';

/** Initializes from the module bytes, synchronously. A no-op when already initialized. */
export function initWasmSync(bytes: BufferSource): WasmExports {
  if (_exports) return _exports;
  _exports = initWasmModuleSync({ module: bytes }) as unknown as WasmExports;
  return _exports;
}

/**
 * Initializes the module (once; later calls return the same promise). In a browser the module
 * is fetched as the `core` stage (progress, stall reports, the library's cache for a versioned
 * URL: fetch.ts) and compiled from its bytes.
 */
export function initWasm(url?: string | URL, options: Pick<FetchOptions, 'onProgress' | 'stallMs'> = {}): Promise<WasmExports> {
  if (_exports) return Promise.resolve(_exports);
  if (options.onProgress) _listeners.add(options.onProgress);
  _pending ??= (async () => {
    if (isNode() && url === undefined) {
      // Kept out of the browser bundle: the specifier is not a literal a bundler can follow.
      const fsModule = 'node:fs/promises';
      const { readFile } = (await import(/* @vite-ignore */ fsModule)) as { readFile(path: URL): Promise<Uint8Array<ArrayBuffer>> };
      // The package: the shipped file (a file: URL beside dist/lib/). The source (vitest): the
      // generated package beside this file, not `new URL('literal', import.meta.url)`, which
      // our own build would inline into the JS.
      const file = PACKAGE ? assetUrl('mmcore_bg.wasm') : new URL(['pkg', 'mmcore_bg.wasm'].join('/'), import.meta.url);
      file.search = '';
      return initWasmSync(await readFile(file));
    }
    const where = String(url ?? assetUrl('mmcore_bg.wasm'));
    try {
      const bytes = await fetchBytes(where, { stage: 'core', stallMs: options.stallMs, onProgress: (p) => _listeners.forEach((l) => l(p)) });
      _exports = (await initWasmModule({ module_or_path: bytes })) as unknown as WasmExports;
      mark('mm:core-ready'); // compiled and instantiated (load benchmarks: scripts/bench-load.mjs)
    } catch (e) {
      _pending = null;
      const message = e instanceof Error ? e.message : String(e);
      throw new Error(message.includes(where) ? message : `could not load the motion-matching core ${where}: ${message}`);
    } finally {
      _listeners.clear();
    }
    return _exports;
  })();
  return _pending;
}

/** The module's exports; throws if `initWasm()` / `initWasmSync()` has not completed. */
export function wasmExports(): WasmExports {
  if (!_exports) throw new Error('the motion-matching core is not initialized: await initWasm() first');
  return _exports;
}

/** The WASM linear memory. Its `buffer` is replaced (and old views detached) when memory grows. */
export function wasmMemory(): WebAssembly.Memory {
  return wasmExports().memory;
}

/** Live WASM objects and the module's memory size: what a page can watch for leaks. */
export interface LiveObjects {
  databases: number;
  characters: number;
  crowds: number;
  retargeters: number;
  builders: number;
  /** Bytes of WASM linear memory (it never shrinks; freed memory is reused). */
  memoryBytes: number;
}

export function liveObjects(): LiveObjects {
  const counts = JSON.parse(live_objects()) as Omit<LiveObjects, 'memoryBytes'>;
  return { ...counts, memoryBytes: wasmMemory().buffer.byteLength };
}

/** wasm-bindgen may throw a string rather than an Error. */
export function asError(e: unknown): Error {
  return e instanceof Error ? e : new Error(String(e));
}

/** The `Raw*` classes by the name of their export `__wbg_<kind>_free`. */
export type RawKind = 'rawbuilder' | 'rawcharacter' | 'rawcrowd' | 'rawdatabase' | 'rawretargeter' | 'rawsearchindex' | 'rawtwoboneik';

/**
 * Frees a `Raw*` object, even one a trap left behind. A trap (`WebAssembly.RuntimeError`: out
 * of memory, a bug) aborts the Rust call without running its drops, so the object stays marked
 * as borrowed by that call and its `free()` throws "attempted to take ownership of Rust value
 * while it was borrowed", keeping its memory for ever. Nothing can use that borrow any more
 * (its call is gone), so here its reference is released too and the object is dropped — as if
 * the call had ended. Every wrapper in this folder frees through this.
 */
export function freeRaw(raw: { free(): void }, kind: RawKind): void {
  const ptr = (raw as unknown as { __wbg_ptr?: number }).__wbg_ptr ?? 0;
  try {
    raw.free();
  } catch (e) {
    if (!(e instanceof Error && e.message.includes('while it was borrowed')) || ptr === 0) throw e;
    const free = (wasmExports() as unknown as Record<string, unknown>)[`__wbg_${kind}_free`];
    if (typeof free !== 'function') throw e;
    (free as (ptr: number, allowDelayed: number) => void)(ptr, 1);
  }
}
