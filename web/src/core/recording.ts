/**
 * The recording validator of the runtime (wraps `validate_recording`, wasm-core/src/runtime/recording.rs):
 * the page and `mmdb replay` check a VR recording with the same code, so the CLI accepts exactly
 * the recordings the page replays. Needs the WASM module (`initWasm()`).
 */
import { validate_recording } from './raw.ts';
import { wasmExports } from './wasm.ts';

/** A decoded recording's arrays (SoA over frames; see `web/src/vr/recording.ts`). */
export interface RecordingValues {
  readonly frames: number;
  readonly time: Float64Array;
  readonly position: Float64Array;
  readonly rotation: Float64Array;
  readonly tracked: Uint8Array;
  readonly truth?: { readonly bodyYaw: Float64Array; readonly root: Float64Array };
  readonly body?: { readonly joints: readonly string[]; readonly position: Float64Array; readonly rotation: Float64Array; readonly tracked: Uint8Array };
}

/** Throws an Error with the first thing wrong (`time must increase: …`); no prefix. */
export function validateRecordingValues(r: RecordingValues): void {
  wasmExports(); // a clear error when the module is not initialized
  const empty = new Float64Array(0);
  const b = r.body;
  try {
    validate_recording(r.frames, r.time, r.position, r.rotation, r.tracked, r.truth !== undefined, r.truth?.bodyYaw ?? empty, r.truth?.root ?? empty,
      b?.joints.length ?? 0, b?.position ?? empty, b?.rotation ?? empty, b?.tracked ?? new Uint8Array(0));
  } catch (e) {
    throw e instanceof Error ? e : new Error(String(e));
  }
}
