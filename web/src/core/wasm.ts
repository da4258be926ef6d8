/**
 * Loads the `mmcore` WASM module once and exposes its linear memory.
 *
 * Browser: `initWasm()` fetches `pkg/mmcore_bg.wasm` (built by scripts/setup.mjs).
 * Node (vitest, scripts): `initWasm()` reads the same file from disk, or call
 * `initWasmSync(bytes)` with the module's bytes.
 */
import init, { initSync } from './pkg/mmcore.js';

/** What the module's initializer returns: its exports, including `memory`. */
export interface WasmExports {
  readonly memory: WebAssembly.Memory;
}

let _exports: WasmExports | null = null;
let _pending: Promise<WasmExports> | null = null;

const isNode = typeof process !== 'undefined' && !!process.versions?.node && typeof window === 'undefined';

/** Initializes from the module bytes, synchronously. A no-op when already initialized. */
export function initWasmSync(bytes: BufferSource): WasmExports {
  if (_exports) return _exports;
  _exports = initSync({ module: bytes }) as unknown as WasmExports;
  return _exports;
}

/** Initializes the module (once; later calls return the same promise). */
export function initWasm(): Promise<WasmExports> {
  if (_exports) return Promise.resolve(_exports);
  _pending ??= (async () => {
    if (isNode) {
      // Kept out of the browser bundle: the specifier is not a literal vite can follow.
      const fsModule = 'node:fs/promises';
      const { readFile } = (await import(/* @vite-ignore */ fsModule)) as typeof import('node:fs/promises');
      const bytes = await readFile(new URL('./pkg/mmcore_bg.wasm', import.meta.url));
      return initWasmSync(bytes);
    }
    _exports = (await init()) as unknown as WasmExports;
    return _exports;
  })();
  return _pending;
}

/** The module's exports; throws if `initWasm()` / `initWasmSync()` has not completed. */
export function wasmExports(): WasmExports {
  if (!_exports) throw new Error('mmcore WASM module is not initialized: await initWasm() first');
  return _exports;
}

/** The WASM linear memory. Its `buffer` is replaced (and old views detached) when memory grows. */
export function wasmMemory(): WebAssembly.Memory {
  return wasmExports().memory;
}
