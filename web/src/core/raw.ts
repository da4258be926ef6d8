/**
 * The only importer of the generated WASM package (`./pkg`, built by scripts/setup.mjs): the
 * raw layer's front. Everything else in the library reaches the `Raw*` classes through here,
 * wrapped one class per file (this folder mirrors `wasm-core/src/bindings/` file for file).
 */
export {
  default as initWasmModule,
  initSync as initWasmModuleSync,
  bvh_info,
  find_roles_json,
  find_roles_rest_json,
  is_closed_mesh,
  live_objects,
  role_names_json,
  validate_recording,
  RawBuilder,
  RawCharacter,
  RawCrowd,
  RawDatabase,
  RawRetargeter,
  RawSearchIndex,
  RawTwoBoneIk,
} from './pkg/mmcore.js';
