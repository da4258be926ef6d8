/**
 * The pages' own kit (demo, viewer, VR, bench): scene views, page helpers (error box and error
 * report, loading status, drop target, file save, the page's character loader, the demo's panel
 * helpers, the VR page's controls and emulated headset) and the benchmarks. Internal: not in the
 * package's `exports`, not part of its API; the pages may import it and the public entries,
 * nothing else (`tests/unit/structure.test.ts`). Library logic stays in the library: these only
 * wire it to a page.
 */

// Scene views.
export { SkeletonView } from '../views/skeleton-view.ts';
export { PathEditor } from '../views/path-editor.ts';
export { RootMarker } from '../views/root-marker.ts';
export { Playback } from '../views/playback.ts';
export { UpdateTimer } from '../views/update-timer.ts';
export { createMirror } from '../views/mirror.ts';
export { ControllerMarkers } from '../views/controller-markers.ts';

// Page helpers.
export { droppedDatabase, installDropTarget } from '../ui/drop.ts';
export type { DroppedFiles } from '../ui/drop.ts';
export { showError } from '../ui/error-box.ts';
export { catchPageErrors } from '../ui/page-errors.ts';
export { LoadingStatus } from '../ui/loading-status.ts';
export { loadPageCharacter } from '../ui/page-loader.ts';
export type { PageCharacter, PageCharacterOptions } from '../ui/page-loader.ts';
export { addSettingsFolders, setOptions } from '../ui/settings-gui.ts';
export { RecordButton } from '../ui/record-button.ts';
export { YawPredictorChoice } from '../ui/yaw-predictor-choice.ts';
export { emulateQuest3 } from '../ui/xr-emulator.ts';

// Benchmarks (bench.html, scripts/bench.mjs).
export { benchSearch } from '../bench/search-bench.ts';
export type { MethodTiming, SearchBenchOptions, SearchBenchResult } from '../bench/search-bench.ts';
export { benchRuntime } from '../bench/runtime-bench.ts';
export type { RuntimeBenchResult } from '../bench/runtime-bench.ts';
// Fetching with progress and the error text the pages show.
export { errorMessage, fetchBytes } from '../fetch.ts';
