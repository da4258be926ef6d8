/**
 * The crowd (crowd.html): `n` motion-matched characters on one shared database, each with a
 * clone of one avatar (geometry, materials and textures shared: one download, one shader
 * compile), walking from goal to goal and steering crudely around each other. Farther
 * characters update less often (level of detail: every frame near the camera, every 2nd frame
 * past 20 m, every 4th past 32 m; their `dt` accumulates). The HUD splits the CPU per frame per
 * character updated into the runtime (drive + search + playback: `applyDrive` + `advance`), the
 * pose (retarget, bones, grounding: `pose`) and the render (bone uploads and draw calls), with the
 * draw calls. The public entry only.
 *
 * URL parameters: `n=200` (1–1000), `lod=0` (every character every frame), `dt=fixed` (1/60 s a
 * frame, for the bench; `dt=0.1`: that many s), `steps=1` (updates per drawn frame, 1–16),
 * `seed=1`, `skinning=three` (three.js poses the bones and skins instead of the core:
 * `Avatar.coreSkinning`). Tests and `npm run bench -- --crowd`: `window.__crowd`.
 */
import * as THREE from 'three';
import {
  Avatar, Character, DEFAULT_AVATAR, DEFAULT_DATABASE, FollowCamera, Stage, assetUrl,
  loadDatabase,
} from '../../index.ts';
import { catchPageErrors, errorMessage } from '../kit.ts';

const params = new URLSearchParams(location.search);
const n = Math.max(1, Math.min(1000, Math.floor(Number(params.get('n') ?? 200)) || 200));
const lod = params.get('lod') !== '0';
const core = params.get('skinning') !== 'three';
const fixedDt = params.get('dt') === 'fixed' ? 1 / 60 : Math.min(0.25, Number(params.get('dt')) || 0);
const steps = Math.max(1, Math.min(16, Math.floor(Number(params.get('steps'))) || 1));

/** Per frame, per character updated (ms): medians over the last `WINDOW` frames (`window=60`). */
const WINDOW = Math.max(1, Number(params.get('window')) || 60);
const hook = {
  ready: false,
  error: null as string | null,
  n,
  lod,
  crossOriginIsolated,
  frames: 0,
  /** Characters updated an update, mean over the window's frames. */
  updatedMean: NaN,
  /** Updates run (`steps` per drawn frame); the levels of detail count updates as frames. */
  updates: 0,
  /** Character updates in the last update by level (every update, every 2nd, every 4th). */
  levels: [0, 0, 0],
  perCharacter: { runtime: NaN, pose: NaN, render: NaN },
  /** All characters this frame (ms, its updates together) and the draw calls. */
  frame: { runtime: NaN, pose: NaN, render: NaN, drawCalls: 0, updated: 0 },
  /** Root (x, z) of every character (at the start and every 15 updates), and how many are not finite (last update). */
  positions: [] as number[],
  start: [] as number[],
  /** What the GPU holds (shared by the clones: a handful, not one set per character). */
  memory: { geometries: 0, textures: 0, programs: 0 },
  notFinite: 0,
};
declare global {
  interface Window {
    __crowd: typeof hook;
  }
}
window.__crowd = hook;
catchPageErrors(hook);
const hud = document.getElementById('hud')!;

/** A small seeded generator (mulberry32): the same crowd for the same `seed`. */
let seed = Number(params.get('seed') ?? 1) >>> 0;
const random = () => {
  seed = (seed + 0x6d2b79f5) >>> 0;
  let t = seed;
  t = Math.imul(t ^ (t >>> 15), t | 1);
  t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
  return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
};

// The area grows with the crowd (~4.5 m² each): 200 people in 30 × 30 m.
const half = Math.sqrt(n * 4.5) / 2;
const point = (): [number, number] => [(random() * 2 - 1) * half, (random() * 2 - 1) * half];

const stage = new Stage(document.getElementById('viewport')!);
stage.scene.fog = new THREE.Fog(0x1d2126, half * 2.5, half * 5);
stage.camera.far = half * 8;
stage.camera.position.set(0, half * 0.65, half * 1.45);
const orbit = new FollowCamera(stage.camera, stage.renderer.domElement);
orbit.controls.maxDistance = half * 5;
orbit.targetHeight = 0;

interface Walker {
  character: Character;
  goal: [number, number];
  /** Stick amount (walking pace) and the time this character has not been updated for. */
  pace: number;
  pending: number;
  /** Last root (x, z) read. */
  x: number;
  z: number;
}
const walkers: Walker[] = [];

async function start(): Promise<void> {
  hud.textContent = `loading the database and the avatar for ${n} characters…`;
  const [database, template] = await Promise.all([
    loadDatabase(assetUrl(DEFAULT_DATABASE)),
    Avatar.load(assetUrl(DEFAULT_AVATAR)),
  ]);
  for (let i = 0; i < n; i++) {
    const character = new Character(database, i === 0 ? template : template.clone());
    character.avatar!.coreSkinning = core; // bone and skin matrices from the core's FK
    const [x, z] = point();
    character.teleport(x, z, random() * Math.PI * 2);
    stage.scene.add(character.object3d);
    walkers.push({ character, goal: point(), pace: 0.55 + 0.45 * random(), pending: 0, x, z });
  }
  database.release(); // the characters hold it
  hook.start = walkers.flatMap((w) => [w.x, w.z]);
  hook.ready = true;
  let last = performance.now();
  stage.renderer.setAnimationLoop((now) => {
    frame(fixedDt || Math.min(0.1, (now - last) / 1000) / steps);
    last = now;
  });
}

/** How often (in updates: frames when `steps` is 1) a character this far from the camera is updated. */
function every(distance: number): number {
  if (!lod || distance < 20) return 1;
  return distance < 32 ? 2 : 4;
}

/** Steering: toward the goal, away from neighbours closer than 1.2 m (a new goal once there). */
function steer(w: Walker, i: number): [number, number] {
  let [dx, dz] = [w.goal[0] - w.x, w.goal[1] - w.z];
  const d = Math.hypot(dx, dz);
  if (d < 1) w.goal = point();
  [dx, dz] = d > 1e-6 ? [dx / d, dz / d] : [0, 0];
  for (let j = 0; j < walkers.length; j++) {
    const o = walkers[j];
    const [ox, oz] = [w.x - o.x, w.z - o.z];
    const r2 = ox * ox + oz * oz;
    if (j === i || r2 > 1.44 || r2 < 1e-8) continue;
    const r = Math.sqrt(r2);
    const push = (1.2 - r) / 1.2 / r; // unit away, stronger the closer
    dx += 2 * ox * push;
    dz += 2 * oz * push;
  }
  const l = Math.hypot(dx, dz) || 1;
  return [(dx / l) * w.pace, (dz / l) * w.pace];
}

const samples = { runtime: [] as number[], pose: [] as number[], render: [] as number[], updated: [] as number[] };
const median = (v: number[]) => [...v].sort((a, b) => a - b)[v.length >> 1] ?? NaN;
const due: Walker[] = [];
const dts: number[] = [];

/** `steps` updates, then one drawn frame. */
function frame(dt: number): void {
  const f = hook.frame;
  f.runtime = f.pose = f.updated = 0;
  for (let s = 0; s < steps; s++) update(dt);
  const t2 = performance.now();
  orbit.follow(0, 0, dt * steps);
  stage.render();
  const t3 = performance.now();
  f.render = t3 - t2;
  f.drawCalls = stage.renderer.info.render.calls;
  const { geometries, textures } = stage.renderer.info.memory;
  Object.assign(hook.memory, { geometries, textures, programs: stage.renderer.info.programs?.length ?? 0 });
  const per = (ms: number) => ms / Math.max(1, f.updated);
  const frameSamples = [
    ['runtime', per(f.runtime)],
    ['pose', per(f.pose)],
    ['render', f.render],
    ['updated', f.updated / steps],
  ] as const;
  for (const [key, ms] of frameSamples) {
    const s = samples[key];
    s.push(ms);
    if (s.length > WINDOW) s.shift();
  }
  const p = hook.perCharacter;
  [p.runtime, p.pose, p.render] = [median(samples.runtime), median(samples.pose), median(samples.render) / n];
  hook.updatedMean = samples.updated.reduce((a, b) => a + b, 0) / samples.updated.length;
  hook.frames++;
  if (hook.frames % 15 === 1) { // from the first frame on: "loading…" never outlives the load
    const ms = (v: number) => `${(v * 1000).toFixed(0)} µs`;
    hud.textContent =
      `${n} people · per person: runtime ${ms(p.runtime)}, pose ${ms(p.pose)}, render ${ms(p.render)} · ` +
      `${f.drawCalls} draw calls · updated ${hook.levels.join('/')} (every frame/2nd/4th)`;
  }
}

/** One update: the characters due (by level of detail) steer, advance and pose. */
function update(dt: number): void {
  const cam = stage.camera.position;
  due.length = dts.length = 0;
  hook.levels.fill(0);
  walkers.forEach((w, i) => {
    w.pending += dt;
    const k = every(Math.hypot(w.x - cam.x, cam.y, w.z - cam.z));
    if ((hook.updates + i) % k !== 0) return;
    hook.levels[k === 1 ? 0 : k === 2 ? 1 : 2]++;
    const [mx, mz] = steer(w, i);
    w.character.setMove(mx, mz);
    due.push(w);
    dts.push(w.pending);
    w.pending = 0;
  });
  const t0 = performance.now();
  for (let i = 0; i < due.length; i++) {
    const c = due[i].character;
    c.applyDrive(c.drive);
    c.advance(dts[i]);
  }
  const t1 = performance.now();
  hook.notFinite = 0;
  for (let i = 0; i < due.length; i++) {
    const w = due[i];
    w.character.pose(dts[i]);
    const r = w.character.root;
    if (!Number.isFinite(r.x) || !Number.isFinite(r.z)) hook.notFinite++;
    [w.x, w.z] = [r.x, r.z];
  }
  const t2 = performance.now();
  const f = hook.frame;
  [f.runtime, f.pose, f.updated] = [f.runtime + t1 - t0, f.pose + t2 - t1, f.updated + due.length];
  hook.updates++;
  if (hook.updates % 15 === 0) hook.positions = walkers.flatMap((w) => [w.x, w.z]);
}

start().catch((e) => {
  hook.error = errorMessage(e);
  hud.textContent = `the crowd could not start: ${hook.error}`;
});
