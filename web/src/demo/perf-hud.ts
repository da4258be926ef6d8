/**
 * The performance HUD: frames per second (median frame time), animation time per frame (runtime
 * update, forward kinematics and retargeting), and the runtime update time on frames that ran a
 * search — over the last 64 frames, since single frames are noisy. Also the line saying what plays
 * (clip, frame, tags, search cost). Text is written a few times a second, never per frame.
 */
import { type Crowd } from '../core/crowd.ts';

const WINDOW = 64;

/** A ring of recent samples with an allocation-free median. */
class Samples {
  private readonly values = new Float64Array(WINDOW);
  private readonly sorted = new Float64Array(WINDOW);
  private count = 0;
  private next = 0;

  push(v: number): void {
    this.values[this.next] = v;
    this.next = (this.next + 1) % WINDOW;
    this.count = Math.min(WINDOW, this.count + 1);
  }

  /** Mean: unbiased for timings quantized by a coarse clock (Chromium: 0.1 ms), unlike the median. */
  mean(): number {
    if (this.count === 0) return NaN;
    let sum = 0;
    for (let i = 0; i < this.count; i++) sum += this.values[i];
    return sum / this.count;
  }

  median(): number {
    if (this.count === 0) return NaN;
    const s = this.sorted.subarray(0, this.count);
    s.set(this.values.subarray(0, this.count));
    s.sort();
    return s[this.count >> 1];
  }
}

export class PerfHud {
  private readonly frameMs = new Samples();
  private readonly animMs = new Samples();
  private readonly searchMs = new Samples();
  private last = -1;
  private shownAt = 0;

  constructor(private readonly element: HTMLElement) {}

  /**
   * One rendered frame at `now` (ms): runtime update time, whole animation time, and whether
   * the update ran a search.
   */
  frame(now: number, updateMs: number, animMs: number, searched: boolean): void {
    if (this.last >= 0) this.frameMs.push(now - this.last);
    this.last = now;
    this.animMs.push(animMs);
    if (searched) this.searchMs.push(updateMs);
    if (now - this.shownAt < 250) return;
    this.shownAt = now;
    const fps = 1000 / this.frameMs.median();
    this.element.textContent = `${fps.toFixed(0)} fps · animation ${this.animMs.mean().toFixed(2)} ms · update with search ${this.searchMs.mean().toFixed(2)} ms`;
  }

  /** Writes what plays into `element`: clip, frame, tags there, and the last search's costs. */
  showFrame(element: HTMLElement, rig: { crowd: Crowd }, frame: number): void {
    const crowd = rig.crowd;
    const clip = crowd.clipNames[crowd.binding.clip(0)] ?? '?';
    const tags = crowd.tags.filter((t) => t.ranges.some(([s, e]) => frame >= s && frame < e)).map((t) => t.name);
    const cost = crowd.binding.search_cost(0);
    const best = crowd.binding.best_cost(0);
    element.textContent = `${clip} · frame ${frame}${tags.length ? ` · ${tags.join(', ')}` : ''} · search cost ${cost.toFixed(2)} (last jump: ${best.toFixed(2)})`;
  }
}
