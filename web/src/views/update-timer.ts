/** A ring of the last N frame timings (ms) with median / quantiles, computed without allocating. */
export class UpdateTimer {
  private readonly values: Float64Array;
  private readonly scratch: Float64Array;
  private next = 0;
  count = 0;

  constructor(capacity: number) {
    this.values = new Float64Array(Math.max(1, capacity));
    this.scratch = new Float64Array(Math.max(1, capacity));
  }

  add(ms: number): void {
    this.values[this.next] = ms;
    this.next = (this.next + 1) % this.values.length;
    this.count = Math.min(this.count + 1, this.values.length);
  }

  /** The q-quantile (0–1, nearest rank) of the kept timings; NaN when empty. */
  quantile(q: number): number {
    if (this.count === 0) return NaN;
    const s = this.scratch.subarray(0, this.count);
    s.set(this.values.subarray(0, this.count));
    s.sort();
    return s[Math.min(this.count - 1, Math.max(0, Math.round(q * (this.count - 1))))];
  }

  median(): number {
    return this.quantile(0.5);
  }

  mean(): number {
    let sum = 0;
    for (let i = 0; i < this.count; i++) sum += this.values[i];
    return this.count ? sum / this.count : NaN;
  }
}
