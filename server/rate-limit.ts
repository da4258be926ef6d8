/**
 * A token bucket: `capacity` tokens, refilled at `rate` tokens a second; `take(n)` fails (and
 * takes nothing) when fewer than n are left. Time comes from the caller (ms), so tests drive it.
 */
export class TokenBucket {
  private tokens: number;
  private last: number;

  constructor(
    readonly rate: number,
    readonly capacity: number,
    nowMs: number,
  ) {
    this.tokens = capacity;
    this.last = nowMs;
  }

  take(n: number, nowMs: number): boolean {
    const elapsed = Math.max(0, nowMs - this.last) / 1000;
    this.last = nowMs;
    this.tokens = Math.min(this.capacity, this.tokens + elapsed * this.rate);
    if (n > this.tokens) return false;
    this.tokens -= n;
    return true;
  }

  get available(): number {
    return this.tokens;
  }
}

/** What one connection may send (defaults in `DEFAULT_LIMITS`; docs/rooms.md, Safety). */
export interface RateLimits {
  /** Messages a second, sustained, and the burst. A client sends 20–30 inputs + 1 state a second. */
  messagesPerSecond: number;
  messageBurst: number;
  /** Bytes a second, sustained, and the burst (a VR member sends ~3.3 KB/s). */
  bytesPerSecond: number;
  byteBurst: number;
  /** Simulation steps a second (a 240 Hz display) and the burst. */
  stepsPerSecond: number;
  stepBurst: number;
  /**
   * Simulated seconds per real second, and the burst (s): a sender cannot make receivers
   * simulate faster than real time (each step costs every receiver CPU).
   */
  simSecondsPerSecond: number;
  simSecondBurst: number;
  /** JOIN (profile updates) a second and the burst. */
  joinsPerSecond: number;
  joinBurst: number;
}

export const DEFAULT_LIMITS: RateLimits = {
  messagesPerSecond: 60,
  messageBurst: 120,
  bytesPerSecond: 12_000,
  byteBurst: 24_000,
  stepsPerSecond: 260,
  stepBurst: 520,
  simSecondsPerSecond: 1.2,
  simSecondBurst: 3,
  joinsPerSecond: 0.5,
  joinBurst: 3,
};
