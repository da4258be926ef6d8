/**
 * The database viewer (viewer.html): every frame of a `.mmdb` (default the locomotion database,
 * or `?db=<url>`) in order on its skeleton, with the virtual root, foot contacts, a scrubber and
 * a HUD. `?frame=N` starts at frame N, `?paused` starts paused (links to a moment). State for
 * tests is on `window.__viewer`. Only the library's public entry and the pages' kit are used.
 */
import { DEFAULT_DATABASE, Database, assetUrl, registerOfflineCache, FollowCamera, Stage } from '../../index.ts';
import { LoadingStatus, Playback, RootMarker, SkeletonView, catchPageErrors, errorMessage, showError } from '../kit.ts';

const hook = { numFrames: 0, frame: 0, playing: false, clipName: '', error: null as string | null, ready: false };
declare global {
  interface Window {
    __viewer: typeof hook;
  }
}
window.__viewer = hook;

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const button = $<HTMLButtonElement>('play');
const scrubber = $<HTMLInputElement>('scrubber');
const hud = $('hud');

const fail = catchPageErrors(hook, (message) => {
  showError(message);
  if (!hook.ready) {
    // Nothing to play: say so in the toolbar instead of "loading…".
    button.disabled = scrubber.disabled = true;
    hud.textContent = 'no database loaded';
  }
});

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  let stage: Stage;
  try {
    stage = new Stage($('viewport'));
  } catch (e) {
    return fail(`WebGL is not available: ${errorMessage(e)}`);
  }
  const camera = new FollowCamera(stage.camera, stage.renderer.domElement);
  stage.render();
  let db: Database;
  const loading = LoadingStatus.attach(hud); // each stage with its URL and bytes; stalls; Retry
  try {
    db = await Database.fetch(params.get('db') ?? assetUrl(DEFAULT_DATABASE), { onProgress: loading.update });
  } catch (e) {
    fail(errorMessage(e));
    return loading.fail(errorMessage(e), () => location.reload());
  }
  if (db.numFrames === 0) return fail(`${db.name}: the database has no frames`);

  // Feet colored by contact: the database's own roles (its site table).
  const feet = (side: string) =>
    ['foot', 'toe'].map((p) => db.roles.get(`${side}_${p}` as 'left_foot')).filter((j): j is number => j !== undefined);
  const skeleton = new SkeletonView(db.jointParents, feet('left'), feet('right'));
  const root = new RootMarker();
  stage.scene.add(skeleton.object, root.object);

  const playback = new Playback(db.numFrames, db.fps);
  playback.seek(Number(params.get('frame') ?? 0) || 0);
  if (params.has('paused')) playback.toggle();
  hook.numFrames = db.numFrames;

  // Toolbar: play/pause, scrubber (not moved under a dragging thumb), space and arrow keys.
  let drawn = -1;
  let shown = '';
  let dragging = false;
  scrubber.max = String(db.numFrames - 1);
  button.addEventListener('click', () => playback.toggle());
  scrubber.addEventListener('pointerdown', () => (dragging = true));
  window.addEventListener('pointerup', () => (dragging = false));
  scrubber.addEventListener('input', () => playback.seek(Number(scrubber.value)));
  window.addEventListener('keydown', (e) => {
    if (e.target instanceof HTMLInputElement && e.key !== ' ') return;
    if (e.key === ' ') {
      e.preventDefault();
      playback.toggle();
    } else if (e.key === 'ArrowRight' || e.key === 'ArrowLeft') {
      playback.playing = false;
      playback.step(e.key === 'ArrowRight' ? 1 : -1);
    }
  });

  let last = performance.now();
  let rootX = 0;
  let rootZ = 0;
  stage.renderer.setAnimationLoop((now: number) => {
    const dt = Math.max(0, (now - last) / 1000);
    last = now;
    playback.update(dt);
    const frame = playback.frame;
    if (frame !== drawn) {
      const positions = db.worldPositions(frame); // the runtime's FK
      const contacts = db.contacts;
      skeleton.update(positions, contacts[frame * 2] !== 0, contacts[frame * 2 + 1] !== 0);
      root.update(positions, db.worldRotations());
      [rootX, rootZ] = [positions[0], positions[2]];
      drawn = frame;
    }
    camera.follow(rootX, rootZ, dt);
    stage.follow(rootX, rootZ);
    const clipName = db.clips[db.clipAt(frame)]?.name ?? '';
    const text = `clip ${clipName} · frame ${frame} / ${db.numFrames} · ${db.fps} fps`;
    if (text !== shown) {
      hud.textContent = shown = text;
      if (!dragging) scrubber.value = String(frame);
    }
    button.textContent = playback.playing ? 'Pause' : 'Play';
    stage.render();
    if (!hook.ready) void registerOfflineCache(); // after the first frame
    [hook.frame, hook.playing, hook.clipName, hook.ready] = [frame, playback.playing, clipName, true];
  });
}

main().catch((e) => fail(errorMessage(e)));
