/**
 * `<mm-avatar>`: a motion-matched character in any web page, built on the public API
 * (`Character`, `Stage`, `MoveControls`). The contract (README "Embed it"):
 *
 * - attributes, all optional: `avatar` (GLB/VRM URL; default the shipped avatar; `none`: the
 *   skeleton), `database` (.mmdb URL; default the shipped locomotion database), `controls`
 *   (space-separated `keyboard gamepad path none`; default `keyboard gamepad`; the keyboard
 *   acts only while the element has focus), `camera` (`follow`: moves with the character;
 *   `fixed`: stays put and turns to keep it in view), `loading` (`eager` | `lazy`: wait until
 *   near the viewport and the eager ones drew), `motion-style` (one of the database's styles,
 *   e.g. `angry`; default `neutral`), `debug`, `alt`;
 * - properties and methods: `character`, `root` ({x, y, z, yaw}, m / rad, the element's floor
 *   frame), `walkTo(x, z, {run})`, `setMove(x, z, {run})`, `stop()`, `ready` (a promise), `room`
 *   (the shared room its character is in, or null: `room.list()` — docs/rooms.md), and
 *   `timeStep` (null: real time; a number: fixed seconds per frame, for tests and recordings),
 *   `stepsPerFrame` (updates per drawn frame, 1–16: simulate faster than the screen draws);
 * - events: `progress` (`detail: {stage, loaded, total, url, stalled, done, cached}`), `load`
 *   (first animated frame), `error` (`detail: {message, url}`), and a visible status inside the
 *   element: each stage with its URL and bytes, a stalled download after 5 s, a failed database
 *   with a Retry button (`retry()`), a failed avatar's note over the skeleton;
 * - a value it does not understand (a typo in `controls`, `camera`, `loading` or
 *   `motion-style`, a refused `timeStep` or `stepsPerFrame`) is a console warning kept in
 *   `warnings`, and the default is used; a `database`/`avatar` that is not a fetchable URL is an
 *   error shown in the element;
 * - removing the element frees its WASM memory and GPU objects; adding it again rebuilds it.
 */
import * as THREE from 'three';
import { DEFAULT_AVATAR, DEFAULT_FIRST_PART, assetUrl } from '../assets.ts';
import { Avatar } from '../avatar/avatar.ts';
import { loadSharedAvatar } from '../avatar/shared.ts';
import { Character, type MoveOptions, type PathOptions, type Root } from '../character/character.ts';
import { type Database, loadDatabase, loadDefaultDatabase } from '../core/database.ts';
import { checkStepsPerFrame, checkTimeStep, parseChoice, parseControls, parseUrl, quote } from './attributes.ts';
import { type FetchProgress, errorMessage, mark } from '../fetch.ts';
import { MoveControls } from '../input/move-controls.ts';
import { roomOf } from '../rooms/room-of.ts';
import type { RoomSession } from '../rooms/room-session.ts';
import { LoadingStatus } from '../ui/loading-status.ts';
import { FollowCamera } from '../views/follow-camera.ts';
import { Stage } from '../views/stage.ts';

const STYLE = `
:host { display: block; position: relative; width: 100%; height: 360px; overflow: hidden; background: #1d2126; border-radius: 6px; outline: none; contain: content; }
:host(:focus-visible) { box-shadow: 0 0 0 3px #7aa7ff; }
.view { position: absolute; inset: 0; }
.view canvas { display: block; width: 100%; height: 100%; touch-action: none; }
.status { position: absolute; left: 0; right: 0; bottom: 0; padding: 6px 10px; font: 13px/1.35 system-ui, sans-serif; color: #e6e9ee; background: rgba(20, 23, 28, 0.82); pointer-events: none; }
.status[hidden] { display: none; }
.status.error { color: #ffd2cc; background: rgba(90, 20, 20, 0.88); pointer-events: auto; }
.status.stalled { color: #ffe9b8; background: rgba(70, 52, 10, 0.88); }
.status button { margin-left: 8px; font: inherit; color: #fff; background: #8a2b2b; border: 1px solid #c46; border-radius: 4px; padding: 2px 10px; cursor: pointer; }
.hint { position: absolute; right: 8px; top: 6px; font: 11px system-ui, sans-serif; color: #9aa3ad; pointer-events: none; }
`;

export interface ProgressDetail extends FetchProgress {}

export interface ErrorDetail {
  message: string;
  url: string;
}


const _look = new THREE.Vector3();
const _ndc = new THREE.Vector2();
const _ray = new THREE.Raycaster();
const _floor = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);
const _hit = new THREE.Vector3();

/** `HTMLElement` where there is one: the module also loads in Node (SSR, tests) without a DOM. */
const ElementBase = (typeof HTMLElement === 'undefined' ? class {} : HTMLElement) as typeof HTMLElement;

/**
 * Lazy elements in view start once the page's eager ones have drawn their first frame (or failed,
 * or left, or 2 s have passed): the first character a visitor sees is then not held back by the
 * others' WebGL contexts, shaders and characters on the one main thread and the one GPU process
 * (the embed page's first frame: 373 → 354 ms warm, medians of 8 interleaved visits).
 */
const eagerGate = { pending: 0, waiters: [] as (() => void)[] };
function afterEager(): Promise<void> {
  if (eagerGate.pending === 0) return Promise.resolve();
  return new Promise((start) => {
    eagerGate.waiters.push(start);
    setTimeout(start, 2000);
  });
}

export class MMAvatarElement extends ElementBase {
  static readonly observedAttributes = ['avatar', 'database', 'controls', 'camera', 'debug', 'alt', 'motion-style'];

  /** The character, once loaded (null before `load` and after removal). */
  character: Character | null = null;
  /** The element's stage (scene, camera, renderer), once loaded. */
  stage: Stage | null = null;
  /** What the element could not use (an unknown attribute value, a refused property), newest
   * last, at most 20; each is also a console warning. */
  readonly warnings: string[] = [];
  private timeStep_: number | null = null;
  private stepsPerFrame_ = 1;
  /** Resolves at the first animated frame of the current load. */
  ready: Promise<void>;
  /** Called after every update, before rendering (pages read state here; nothing allocated). */
  afterUpdate: ((dt: number) => void) | null = null;
  /** Milliseconds of the last `Character.update` (runtime, retarget). */
  lastUpdateMs = 0;

  private readonly view: HTMLDivElement;
  private readonly status: HTMLDivElement;
  private readonly loading = new LoadingStatus((text, state, retry) => this.render(text, state, retry));
  private readonly controls = new MoveControls();
  /** The camera's orbit controls and following (once loaded): pages may enable zoom here. */
  orbit: FollowCamera | null = null;
  private abort: AbortController | null = null;
  private observer: IntersectionObserver | null = null;
  /** Counted in `eagerGate.pending` until its first frame (see afterEager). */
  private eagerCounted = false;
  private resolveReady: () => void = () => {};
  private last = 0;
  private loadedOnce = false;
  private generation = 0;
  private downAt = { x: 0, y: 0 };
  private pathControl = false;
  private cameraMode: 'follow' | 'fixed' = 'follow';

  constructor() {
    super();
    const shadow = this.attachShadow({ mode: 'open' });
    const style = document.createElement('style');
    style.textContent = STYLE;
    this.view = document.createElement('div');
    this.view.className = 'view';
    this.status = document.createElement('div');
    this.status.className = 'status';
    this.status.setAttribute('role', 'status');
    shadow.append(style, this.view, this.status);
    this.ready = new Promise((r) => (this.resolveReady = r));
    this.addEventListener('pointerdown', (e) => {
      this.downAt = { x: e.clientX, y: e.clientY };
      this.focus({ preventScroll: true });
    });
    this.addEventListener('pointerup', (e) => this.onClick(e));
    // Arrow keys and Space drive the character, not the page's scroll, while it has focus.
    this.addEventListener('keydown', (e) => {
      if (this.controls.keyboardEnabled && /^(Arrow(Up|Down|Left|Right)|Space)$/.test(e.code)) e.preventDefault();
    });
  }

  connectedCallback(): void {
    // A page (or a framework rendering before the script loads) may have set `timeStep` on the
    // element before <mm-avatar> was defined: that own property hides the accessor, so the value
    // would never be checked or used. Take it through the setter instead.
    for (const key of ['timeStep', 'stepsPerFrame'] as const) {
      if (!Object.hasOwn(this, key)) continue;
      const value = (this as Record<string, unknown>)[key];
      delete (this as Record<string, unknown>)[key];
      (this as Record<string, unknown>)[key] = value;
    }
    if (!this.hasAttribute('tabindex')) this.tabIndex = 0;
    this.setAttribute('role', 'img');
    this.updateAlt();
    this.controls.attach(this);
    this.applyControls();
    this.applyCamera();
    const loading = parseChoice('loading', this.getAttribute('loading'), ['eager', 'lazy'] as const, 'eager', (m) => this.warn(m));
    if (loading === 'lazy' && typeof IntersectionObserver !== 'undefined') {
      this.loading.say('Waiting to come into view…');
      this.observer = new IntersectionObserver(
        (entries) => {
          if (entries.some((e) => e.isIntersecting)) {
            this.observer?.disconnect();
            this.observer = null;
            void afterEager().then(() => {
              if (this.isConnected && !this.stage) void this.load();
            });
          }
        },
        { rootMargin: '200px' },
      );
      this.observer.observe(this);
    } else {
      if (!this.eagerCounted) eagerGate.pending++;
      this.eagerCounted = true;
      void this.load();
    }
  }

  /**
   * This eager element drew its first frame, failed or left: lazy ones may start (afterEager) —
   * a frame later, once this one's first frame is on screen. Started in the same task, a lazy
   * element's context, programs and first draw went ahead of it on the main thread and in the
   * GPU process (traced: the first frame shown ~500 ms after it was drawn, on a software GPU).
   */
  private releaseEager(): void {
    if (!this.eagerCounted) return;
    this.eagerCounted = false;
    if (--eagerGate.pending > 0) return;
    const release = () => {
      if (eagerGate.pending === 0) for (const start of eagerGate.waiters.splice(0)) start();
    };
    if (typeof requestAnimationFrame === 'function') requestAnimationFrame(() => setTimeout(release, 0));
    else setTimeout(release, 0);
  }

  disconnectedCallback(): void {
    this.teardown();
    this.controls.dispose();
  }

  attributeChangedCallback(name: string, before: string | null, after: string | null): void {
    if (before === after || !this.isConnected) return;
    if (name === 'controls') this.applyControls();
    else if (name === 'camera') this.applyCamera();
    else if (name === 'alt') this.updateAlt();
    else if (name === 'debug' && this.character) this.character.debug = this.hasAttribute('debug');
    else if (name === 'motion-style') this.applyStyle();
    else if (name === 'avatar' && this.character) void this.swapAvatar();
    else if (name === 'database' && this.loadedOnce) {
      this.teardown();
      void this.load();
    }
  }

  // ---- the API

  /** Seconds per frame, in (0, 1]; null: the real time between frames (clamped to 0.1 s).
   * Anything else is refused with a warning and the previous value stays. */
  get timeStep(): number | null {
    return this.timeStep_;
  }
  set timeStep(value: number | null) {
    this.timeStep_ = checkTimeStep(value, this.timeStep_, (m) => this.warn(m));
  }

  /** Updates per drawn frame, 1 (default) to 16: each advances `timeStep` (or, in real time, the
   * frame's time over their number), then one frame is drawn — a test or a recording simulates
   * at its step while software WebGL draws a few frames a second (in a room, a frame's updates
   * travel with one wall-clock time). Others are refused (warning). */
  get stepsPerFrame(): number {
    return this.stepsPerFrame_;
  }
  set stepsPerFrame(value: number) {
    this.stepsPerFrame_ = checkStepsPerFrame(value, this.stepsPerFrame_, (m) => this.warn(m));
  }

  /** Where the character stands ({x, y, z} m and yaw rad in the element's floor frame). */
  get root(): Root {
    const r = this.character?.root;
    return r ? { x: r.x, y: r.y, z: r.z, yaw: r.yaw } : { x: 0, y: 0, z: 0, yaw: 0 };
  }

  /**
   * The shared room this element's character is in (a `RoomSession` or `RoomPanel` made for it),
   * or null: `room.list()` gives the other members' names and where their avatars are drawn.
   */
  get room(): RoomSession | null {
    return roomOf(this.character);
  }

  /** Walks (or runs) to floor point (x, z) and stops there. */
  walkTo(x: number, z: number, options: PathOptions = {}): void {
    this.need().walkTo(x, z, options);
  }

  /** Move input: direction (x, z) with length 0–1; (0, 0) stands. */
  setMove(x: number, z: number, options: MoveOptions = {}): void {
    this.need().setMove(x, z, options);
  }

  /** Follows keypoints [[x, z], …] (see `Character.followPath`). */
  followPath(points: readonly (readonly [number, number])[], options: PathOptions = {}): void {
    this.need().followPath(points, options);
  }

  stop(): void {
    this.character?.stop();
  }

  /** Client pixel of floor point (x, z) (tests and tools). */
  screenOf(x: number, z: number): { x: number; y: number } {
    const stage = this.stage;
    if (!stage) return { x: NaN, y: NaN };
    const v = new THREE.Vector3(x, 0, z).project(stage.camera);
    const rect = this.view.getBoundingClientRect();
    return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
  }

  private need(): Character {
    if (!this.character) throw new Error('<mm-avatar>: not loaded yet (wait for the "load" event or `await el.ready`)');
    return this.character;
  }

  // ---- loading

  /** The attribute's URL, or the default asset's. Throws on a value that is not a URL. */
  private url(attribute: string, fallback: string): string {
    return parseUrl(attribute, this.getAttribute(attribute), document.baseURI) ?? assetUrl(fallback).href;
  }

  private warn(message: string): void {
    const m = `<mm-avatar> ${message}`;
    if (this.warnings.length >= 20) this.warnings.shift();
    this.warnings.push(m);
    console.warn(m);
  }

  private async load(): Promise<void> {
    const generation = ++this.generation;
    this.abort = new AbortController();
    const signal = this.abort.signal;
    const progress = (p: FetchProgress) => {
      if (generation !== this.generation) return;
      this.loading.update(p);
      this.dispatchEvent(new CustomEvent<ProgressDetail>('progress', { detail: { ...p } }));
    };
    let databaseUrl: string;
    let avatarUrl: string | null;
    try {
      // No `database`: the shipped one, its first part first (the whole follows the first frame).
      databaseUrl = this.url('database', DEFAULT_FIRST_PART);
      avatarUrl = this.getAttribute('avatar')?.trim() === 'none' ? null : this.url('avatar', DEFAULT_AVATAR);
    } catch (e) {
      this.fail(errorMessage(e), this.getAttribute('database') ?? '');
      return;
    }
    this.loading.reset();
    this.loading.say(`Loading · database ${databaseUrl.split('?')[0].split('/').pop()}…`);
    let database: Database;
    let avatar: Avatar | null = null;
    let avatarNote = '';
    // The downloads first: the cache reads and the core's compile go on while the stage is built
    // (~10-30 ms of main thread for a WebGL context in software). Then the stage: its context,
    // and the avatar's shaders as soon as the avatar is here, get ready while the database still
    // downloads (the first frame then only draws).
    let stage: Stage | null = null;
    let databaseHere = false;
    const precompile = (a: Avatar) => {
      // Its programs linked and its pipelines built by the GPU while the rest loads (Stage.warmUp)
      // — only while there is a rest: with the database already here (a repeat visit, from the
      // cache) the first frame follows at once, links them itself and builds its pipelines once.
      if (stage && !databaseHere && generation === this.generation) stage.warmUp(a.object);
      return a;
    };
    const avatarLoad = avatarUrl ? loadSharedAvatar(avatarUrl, { onProgress: progress, signal }).then(precompile, (e: unknown) => e as Error) : Promise.resolve(null);
    const ownDatabase = databaseUrl !== assetUrl(DEFAULT_FIRST_PART).href;
    const databaseLoad = ownDatabase ? loadDatabase(databaseUrl, { onProgress: progress, signal }) : loadDefaultDatabase({ onProgress: progress, signal });
    databaseLoad.then(
      () => (databaseHere = true),
      () => undefined, // awaited below
    );
    try {
      stage = this.stage = new Stage(this.view);
      stage.scene.fog = null;
    } catch (e) {
      this.abort.abort();
      databaseLoad.then((d) => d.release(), () => undefined);
      void avatarLoad.then((a) => a instanceof Avatar && a.dispose());
      this.fail(errorMessage(e), databaseUrl);
      return;
    }
    try {
      database = await databaseLoad;
      const a = await avatarLoad;
      if (a instanceof Avatar) avatar = a;
      else if (a) {
        // A failed avatar is not a failed element: the skeleton walks, and the note says why.
        avatarNote = `Avatar unavailable, showing the skeleton: ${errorMessage(a)}`;
        this.dispatchEvent(new CustomEvent<ErrorDetail>('error', { detail: { message: avatarNote, url: avatarUrl ?? '' } }));
      }
    } catch (e) {
      if (signal.aborted || generation !== this.generation) return;
      this.fail(errorMessage(e), databaseUrl, true);
      return;
    }
    if (signal.aborted || generation !== this.generation) {
      database.release();
      avatar?.dispose();
      return;
    }
    try {
      const character = new Character(database, avatar, { debug: this.hasAttribute('debug') });
      mark('mm:character-ready');
      database.release(); // the character holds its own reference
      this.character = character;
      this.applyStyle();
      stage.scene.add(character.object3d);
      stage.camera.position.set(2.2, 1.8, 4.2);
      this.orbit = new FollowCamera(stage.camera, stage.renderer.domElement);
      this.orbit.controls.enableZoom = false; // the page scrolls, not the camera
      this.orbit.follow(0, 0, 0);
    } catch (e) {
      this.fail(errorMessage(e), databaseUrl);
      return;
    }
    this.loading.finish(avatarNote || null);
    this.last = performance.now();
    stage.renderer.setAnimationLoop((now: number) => this.frame(now, generation));
  }

  private async swapAvatar(): Promise<void> {
    const character = this.character;
    if (!character) return;
    const attr = this.getAttribute('avatar')?.trim();
    if (attr === 'none') {
      character.setAvatar(null);
      return;
    }
    let url = '';
    try {
      url = this.url('avatar', DEFAULT_AVATAR);
      const avatar = await loadSharedAvatar(url, { onProgress: (p) => this.dispatchEvent(new CustomEvent('progress', { detail: { ...p } })) });
      if (this.character === character) character.setAvatar(avatar);
      else avatar.dispose();
    } catch (e) {
      const message = `Avatar unavailable, keeping the current one: ${errorMessage(e)}`;
      this.loading.finish(message);
      this.dispatchEvent(new CustomEvent<ErrorDetail>('error', { detail: { message, url } }));
    }
  }

  private frame(now: number, generation: number): void {
    const character = this.character;
    const stage = this.stage;
    if (!character || !stage || generation !== this.generation) return;
    const steps = this.stepsPerFrame_;
    const dt = this.timeStep_ ?? Math.min(0.1, Math.max(0, (now - this.last) / 1000)) / steps;
    this.last = now;
    stage.camera.getWorldDirection(_look);
    for (let k = 0; k < steps; k++) {
      const input = this.controls.read(_look.x, _look.z, character.root.yaw, dt);
      if (input) character.setInput(input);
      const t0 = performance.now();
      character.update(dt);
      this.lastUpdateMs = performance.now() - t0;
      this.afterUpdate?.(dt);
    }
    const r = character.root;
    if (this.cameraMode === 'follow') this.orbit?.follow(r.x, r.z, dt * steps);
    else if (this.orbit) {
      // A camera on a tripod: it stays where it is and turns to keep the character in view.
      this.orbit.controls.target.set(r.x, this.orbit.targetHeight, r.z);
      this.orbit.controls.update();
    }
    stage.follow(r.x, r.z);
    stage.render();
    if (!this.loadedOnce) {
      this.loadedOnce = true;
      // A first part's whole downloads from now on, before the page's own work on `load`
      // (the character warns if it fails, at its next update).
      character.whole().catch(() => undefined);
      // For load benchmarks: the page's first animated frame (scripts/bench-load.mjs).
      if (performance.getEntriesByName('mm:first-frame').length === 0) performance.mark('mm:first-frame');
      this.releaseEager();
      this.resolveReady();
      this.dispatchEvent(new Event('load'));
    }
  }

  private teardown(): void {
    this.releaseEager();
    this.generation++;
    this.abort?.abort();
    this.abort = null;
    this.observer?.disconnect();
    this.observer = null;
    this.character?.dispose();
    this.character = null;
    this.stage?.dispose();
    this.stage = null;
    this.orbit?.controls.dispose();
    this.orbit = null;
    if (this.loadedOnce) {
      this.loadedOnce = false;
      this.ready = new Promise((r) => (this.resolveReady = r));
    }
  }

  // ---- controls and messages

  private applyControls(): void {
    const controls = parseControls(this.getAttribute('controls'), (m) => this.warn(m));
    this.controls.keyboardEnabled = controls.has('keyboard');
    this.controls.gamepadEnabled = controls.has('gamepad');
    this.pathControl = controls.has('path');
  }

  /**
   * `motion-style`: one of the database's styles (`neutral` when unset); anything else is a
   * warning naming the styles it has, and the current style stays.
   */
  private applyStyle(): void {
    const character = this.character;
    if (!character) return;
    const value = this.getAttribute('motion-style')?.trim() || null;
    const style = value ?? (character.styles.includes('neutral') ? 'neutral' : null);
    if (style === null) return; // a database without styles, and none asked for
    try {
      character.setStyle(style);
    } catch (e) {
      this.warn(`motion-style=${quote(value ?? '')}: ${errorMessage(e)}; keeping ${character.style}`);
    }
  }

  private applyCamera(): void {
    this.cameraMode = parseChoice('camera', this.getAttribute('camera'), ['follow', 'fixed'] as const, 'follow', (m) => this.warn(m));
  }

  /** `controls="path"`: a click on the floor walks there (Shift-click runs). */
  private onClick(e: PointerEvent): void {
    if (!this.pathControl || !this.character || !this.stage || e.button !== 0) return;
    if (Math.hypot(e.clientX - this.downAt.x, e.clientY - this.downAt.y) > 4) return; // an orbit drag
    const rect = this.view.getBoundingClientRect();
    _ndc.set(((e.clientX - rect.left) / rect.width) * 2 - 1, -((e.clientY - rect.top) / rect.height) * 2 + 1);
    _ray.setFromCamera(_ndc, this.stage.camera);
    const p = _ray.ray.intersectPlane(_floor, _hit);
    if (p) this.character.walkTo(p.x, p.z, { run: e.shiftKey });
  }

  private updateAlt(): void {
    this.setAttribute('aria-label', this.getAttribute('alt') ?? 'An animated character');
  }

  /** Loads again after a failure (the Retry button does this). */
  retry(): void {
    this.teardown();
    void this.load();
  }

  /** Shows the status over the view (null hides it), with a Retry button when offered. */
  private render(text: string | null, state: string, retry: (() => void) | null): void {
    this.status.hidden = text === null;
    this.status.textContent = text ?? '';
    this.status.className = `status ${state}`;
    if (retry) {
      const button = document.createElement('button');
      button.type = 'button';
      button.textContent = 'Retry';
      button.addEventListener('click', (e) => (e.stopPropagation(), retry()));
      this.status.append(button);
    }
  }

  private fail(message: string, url: string, retry = false): void {
    this.releaseEager();
    this.loading.fail(message, retry ? () => this.retry() : null);
    this.dispatchEvent(new CustomEvent<ErrorDetail>('error', { detail: { message, url } }));
  }
}

/**
 * Registers `<mm-avatar>` (or another tag name); a no-op when it is already defined, and outside
 * a browser (no `customElements`: server-side rendering, Node), where it returns false.
 */
export function defineMMAvatar(tag = 'mm-avatar'): boolean {
  if (typeof customElements === 'undefined') return false;
  if (!customElements.get(tag)) customElements.define(tag, MMAvatarElement);
  return true;
}

declare global {
  interface HTMLElementTagNameMap {
    'mm-avatar': MMAvatarElement;
  }
}
