/**
 * Database viewer: loads a `.mmdb` (default `databases/locomotion.mmdb`, or `?db=<url>`) in WASM
 * and plays its frames in order as a skeleton, with the virtual root, foot contacts, a scrubber
 * and a HUD. `?frame=N` starts at frame N and `?paused` starts paused (links to a moment).
 * State for tests is on `window.__viewer`.
 */
import { Database } from '../core/database.ts';
import { initWasm } from '../core/wasm.ts';
import { ViewerControls } from './controls.ts';
import { errorMessage, showError } from './error-box.ts';
import { findFootJoints } from './feet.ts';
import { FollowCamera } from './follow-camera.ts';
import { Playback } from './playback.ts';
import { RootMarker } from './root-marker.ts';
import { ViewerScene } from './scene.ts';
import { SkeletonView } from './skeleton-view.ts';
import { installViewerHook } from './test-hook.ts';

const DEFAULT_DB = 'databases/locomotion.mmdb';

const hook = installViewerHook();

function fail(message: string): void {
  hook.error = hook.error ? `${hook.error}\n${message}` : message;
  showError(message);
  console.warn(`[viewer] ${message}`);
  if (!hook.ready) {
    // Nothing to play: say so in the toolbar instead of "loading…".
    (document.getElementById('play') as HTMLButtonElement).disabled = true;
    (document.getElementById('scrubber') as HTMLInputElement).disabled = true;
    (document.getElementById('hud') as HTMLElement).textContent = 'no database loaded';
  }
}

window.addEventListener('error', (e) => fail(`error: ${e.message}`));
window.addEventListener('unhandledrejection', (e) => fail(`error: ${errorMessage(e.reason)}`));

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const dbUrl = params.get('db') ?? DEFAULT_DB;

  let stage: ViewerScene;
  try {
    stage = new ViewerScene(document.getElementById('viewport') as HTMLElement);
  } catch (e) {
    fail(`WebGL is not available: ${errorMessage(e)}`);
    return;
  }
  const camera = new FollowCamera(stage.camera, stage.renderer.domElement);
  stage.render();

  let db: Database;
  try {
    await initWasm();
    db = await Database.fetch(dbUrl);
  } catch (e) {
    fail(errorMessage(e));
    return;
  }
  if (db.numFrames === 0) {
    fail(`${dbUrl}: the database has no frames`);
    return;
  }

  const feet = findFootJoints(db);
  const skeleton = new SkeletonView(db.jointParents, feet.left, feet.right);
  const root = new RootMarker();
  stage.scene.add(skeleton.object, root.object);

  const playback = new Playback(db.numFrames, db.fps);
  playback.seek(Number(params.get('frame') ?? 0) || 0);
  if (params.has('paused')) playback.toggle();
  let drawnFrame = -1;
  let rootX = 0;
  let rootZ = 0;
  const controls = new ViewerControls(playback, () => {
    drawnFrame = -1;
    controls.invalidate();
  });

  hook.numFrames = db.numFrames;

  let last = performance.now();
  stage.renderer.setAnimationLoop((now: number) => {
    const dt = Math.max(0, (now - last) / 1000);
    last = now;
    playback.update(dt);
    const frame = playback.frame;
    if (frame !== drawnFrame) {
      const pos = db.worldPositions(frame);
      const rot = db.worldRotations();
      const contacts = db.contacts; // cached view, recreated only if WASM memory grew
      skeleton.update(pos, contacts[frame * 2] !== 0, contacts[frame * 2 + 1] !== 0);
      root.update(pos, rot);
      rootX = pos[0];
      rootZ = pos[2];
      drawnFrame = frame;
    }
    camera.follow(rootX, rootZ, dt);
    stage.grid.follow(rootX, rootZ);
    const clipName = db.clips[db.clipAt(frame)]?.name ?? '';
    controls.update(clipName);
    stage.render();

    hook.frame = frame;
    hook.playing = playback.playing;
    hook.clipName = clipName;
    hook.ready = true;
  });
}

main().catch((e) => fail(errorMessage(e)));
