/**
 * A playout (jitter) buffer for one remote member's stream. Items carry a sequence number and
 * the sender's time; the buffer maps sender time to local time as
 *
 *   local = sender + offset + delay,
 *
 * `offset` being the smallest transit seen in a sliding window (clock offset + base latency,
 * so the two clocks need no synchronization) and `delay` adapting to the measured jitter: the
 * 95th percentile of (transit − offset) plus the longest span an item covers plus a margin,
 * clamped to [minDelayMs, maxDelayMs]. The mapping in use (offset + delay) follows its target at
 * a bounded slew — the playout clock runs at most ±10% off real time — so neither a new delay
 * nor a shifted offset ever makes the motion jump or freeze.
 *
 * Items come out in sequence order once due: an item covering sender time
 * (time − span, time] is due when `time − span` ≤ the playout time. Duplicates and items older
 * than what was released are dropped; out-of-order arrivals are reordered; a missing sequence
 * number is skipped as soon as a later item is due (reported as `missingBefore`).
 */

export interface JitterBufferOptions {
  /** Delay before any measurement, ms. Default 100. */
  initialDelayMs?: number;
  /** Bounds of the adaptive delay, ms. Defaults 40 and 500. */
  minDelayMs?: number;
  maxDelayMs?: number;
  /** Added to the measured jitter, ms. Default 10. */
  marginMs?: number;
  /** Samples (arrivals) in the measuring window. Default 64 (3 s at 20 Hz). */
  window?: number;
  /** Items held at most (more are refused as 'overflow'). Default 128. */
  capacity?: number;
  /** Largest rate the playout clock may differ from real time while the delay adapts. Default 0.1. */
  slew?: number;
  /** Adapt the delay to the measured jitter (false: stay at initialDelayMs). Default true. */
  adaptive?: boolean;
}

export type PushResult = 'ok' | 'duplicate' | 'late' | 'overflow' | 'invalid';

export interface Released<T> {
  seq: number;
  /** Sender time at the end of the item, ms. */
  time: number;
  span: number;
  item: T;
  /** Sequence numbers skipped right before this one (lost or never sent). */
  missingBefore: number;
}

export interface JitterStats {
  received: number;
  released: number;
  duplicates: number;
  late: number;
  missing: number;
  reordered: number;
  overflow: number;
}

interface Entry<T> {
  seq: number;
  time: number;
  span: number;
  item: T;
}

export class JitterBuffer<T> {
  readonly options: Required<JitterBufferOptions>;
  /** The delay in use (ms: the mapping in use − offset) and the one it is moving to. */
  delayMs: number;
  targetDelayMs: number;
  /** The smallest transit in the window (ms): sender → local clock offset + base latency. */
  offsetMs = NaN;
  /** 95th percentile of transit − offset in the window (ms). */
  jitterMs = 0;
  readonly stats: JitterStats = { received: 0, released: 0, duplicates: 0, late: 0, missing: 0, reordered: 0, overflow: 0 };
  private readonly entries: Entry<T>[] = [];
  /** Last released sequence number (0: none). */
  private lastSeq = 0;
  private maxSeenSeq = 0;
  private readonly transits: Float64Array;
  private readonly spans: Float64Array;
  private readonly sorted: Float64Array;
  private samples = 0;
  private lastClock = NaN;
  /** The sender → local mapping in use (offset + delay), ms; NaN before the first item. */
  private mappingMs = NaN;

  constructor(options: JitterBufferOptions = {}) {
    this.options = {
      initialDelayMs: options.initialDelayMs ?? 100,
      minDelayMs: options.minDelayMs ?? 40,
      maxDelayMs: options.maxDelayMs ?? 500,
      marginMs: options.marginMs ?? 10,
      window: options.window ?? 64,
      capacity: options.capacity ?? 128,
      slew: options.slew ?? 0.1,
      adaptive: options.adaptive ?? true,
    };
    this.delayMs = this.options.initialDelayMs;
    this.targetDelayMs = this.delayMs;
    this.transits = new Float64Array(this.options.window);
    this.spans = new Float64Array(this.options.window);
    this.sorted = new Float64Array(this.options.window);
  }

  get size(): number {
    return this.entries.length;
  }

  /** The last released sequence number. */
  get releasedSeq(): number {
    return this.lastSeq;
  }

  /** Forgets buffered items up to `seq` and expects `seq + 1` next (after a snapshot). */
  skipTo(seq: number): void {
    this.lastSeq = Math.max(this.lastSeq, seq);
    while (this.entries.length && this.entries[0].seq <= this.lastSeq) this.entries.shift();
  }

  /**
   * Makes the buffered item `seq` due at `nowMs`: the items before it are dropped and the playout
   * clock jumps to its start, from where it slews to its target as always. Only for a stream
   * nobody sees yet — a copy waiting for its sender's state plays from that state the moment it
   * arrives instead of a playout delay later; a shown stream never jumps. False if `seq` is not
   * buffered.
   */
  playFrom(seq: number, nowMs: number): boolean {
    const entry = this.entries.find((e) => e.seq === seq);
    if (!entry || !Number.isFinite(this.offsetMs)) return false;
    this.skipTo(seq - 1);
    this.mappingMs = nowMs - (entry.time - entry.span);
    this.lastClock = nowMs;
    this.delayMs = this.mappingMs - this.offsetMs;
    return true;
  }

  push(seq: number, senderTimeMs: number, arrivalMs: number, item: T, spanMs = 0): PushResult {
    if (!Number.isInteger(seq) || seq < 1 || !Number.isFinite(senderTimeMs) || !Number.isFinite(arrivalMs) || !(spanMs >= 0 && spanMs < 60_000)) return 'invalid';
    this.measure(arrivalMs - senderTimeMs, spanMs);
    if (seq <= this.lastSeq) {
      this.stats.late++;
      return 'late';
    }
    // Insert in sequence order (arrivals are almost always in order: scan from the end).
    let i = this.entries.length;
    while (i > 0 && this.entries[i - 1].seq > seq) i--;
    if (i > 0 && this.entries[i - 1].seq === seq) {
      this.stats.duplicates++;
      return 'duplicate';
    }
    if (this.entries.length >= this.options.capacity) {
      this.stats.overflow++;
      return 'overflow';
    }
    if (seq < this.maxSeenSeq) this.stats.reordered++;
    this.maxSeenSeq = Math.max(this.maxSeenSeq, seq);
    this.entries.splice(i, 0, { seq, time: senderTimeMs, span: spanMs, item });
    this.stats.received++;
    return 'ok';
  }

  /** The sender time that plays at local time `nowMs` (NaN before the first item). */
  playoutTime(nowMs: number): number {
    this.slewMapping(nowMs);
    return nowMs - this.mappingMs;
  }

  /** The next item in sequence order if it is due at `nowMs`. */
  pop(nowMs: number): Released<T> | undefined {
    const head = this.entries[0];
    if (!head) return undefined;
    const playout = this.playoutTime(nowMs);
    if (!(head.time - head.span <= playout)) return undefined;
    this.entries.shift();
    const missingBefore = this.lastSeq === 0 ? 0 : head.seq - this.lastSeq - 1;
    this.stats.missing += missingBefore;
    this.stats.released++;
    this.lastSeq = head.seq;
    return { seq: head.seq, time: head.time, span: head.span, item: head.item, missingBefore };
  }

  /** Sequence number of the next buffered item (0 if empty). */
  peekSeq(): number {
    return this.entries[0]?.seq ?? 0;
  }

  /** Sender time of the next buffered item's start (NaN if empty). */
  nextStart(): number {
    const head = this.entries[0];
    return head ? head.time - head.span : NaN;
  }

  private measure(transit: number, span: number): void {
    const n = this.options.window;
    this.transits[this.samples % n] = transit;
    this.spans[this.samples % n] = span;
    this.samples++;
    const count = Math.min(this.samples, n);
    let min = Infinity;
    let maxSpan = 0;
    for (let k = 0; k < count; k++) {
      if (this.transits[k] < min) min = this.transits[k];
      if (this.spans[k] > maxSpan) maxSpan = this.spans[k];
    }
    this.offsetMs = min;
    for (let k = 0; k < count; k++) this.sorted[k] = this.transits[k] - min;
    const view = this.sorted.subarray(0, count);
    view.sort();
    this.jitterMs = view[Math.min(count - 1, Math.floor(0.95 * count))];
    if (this.options.adaptive && this.samples >= 8) {
      const o = this.options;
      this.targetDelayMs = Math.max(o.minDelayMs, Math.min(o.maxDelayMs, this.jitterMs + maxSpan + o.marginMs));
    }
  }

  private slewMapping(nowMs: number): void {
    const elapsed = Number.isFinite(this.lastClock) ? Math.max(0, nowMs - this.lastClock) : 0;
    this.lastClock = nowMs;
    const target = this.offsetMs + this.targetDelayMs;
    if (!Number.isFinite(target)) return;
    if (!Number.isFinite(this.mappingMs)) this.mappingMs = this.offsetMs + this.delayMs;
    const step = elapsed * this.options.slew;
    this.mappingMs += Math.max(-step, Math.min(step, target - this.mappingMs));
    this.delayMs = this.mappingMs - this.offsetMs;
  }
}
