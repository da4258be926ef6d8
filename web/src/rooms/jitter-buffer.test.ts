import { describe, expect, it } from 'vitest';
import { JitterBuffer } from './jitter-buffer.ts';
import { seededRandom } from '../bench/queries.ts';

/** Drains everything due at `now`. */
function drain<T>(b: JitterBuffer<T>, now: number) {
  const out = [];
  for (let r = b.pop(now); r; r = b.pop(now)) out.push(r);
  return out;
}

describe('JitterBuffer', () => {
  it('releases in sequence order despite reordering; drops duplicates and late arrivals', () => {
    const b = new JitterBuffer<number>({ adaptive: false, initialDelayMs: 100 });
    const order = [1, 3, 2, 5, 4, 4, 6, 2, 8, 7];
    const results = order.map((seq) => b.push(seq, seq * 50, 1000 + seq * 50, seq));
    expect(results).toEqual(['ok', 'ok', 'ok', 'ok', 'ok', 'duplicate', 'ok', 'duplicate', 'ok', 'ok']);
    expect(b.stats.reordered).toBe(3); // 2 after 3, 4 after 5, 7 after 8
    const released = drain(b, 10_000).map((r) => r.item);
    expect(released).toEqual([1, 2, 3, 4, 5, 6, 7, 8]);
    expect(b.push(5, 250, 10_001, 5)).toBe('late');
    expect(b.stats).toMatchObject({ received: 8, released: 8, duplicates: 2, late: 1, missing: 0 });
  });

  it('waits for a missing sequence number only until the next item is due, then skips it', () => {
    const b = new JitterBuffer<number>({ adaptive: false, initialDelayMs: 100 });
    // Constant 20 ms transit: offset 20, delay 100 → sender time t plays at local t + 120.
    for (const seq of [1, 2, 4, 5]) b.push(seq, seq * 50, seq * 50 + 20, seq);
    expect(drain(b, 2 * 50 + 120).map((r) => r.seq)).toEqual([1, 2]);
    expect(b.pop(3 * 50 + 120)).toBeUndefined(); // seq 3's time: 4 is not due yet
    expect(b.pop(4 * 50 + 119)).toBeUndefined();
    const r = b.pop(4 * 50 + 120);
    expect(r).toMatchObject({ seq: 4, missingBefore: 1 });
    expect(b.stats.missing).toBe(1);
    expect(b.push(3, 150, 400, 3)).toBe('late'); // arrived after it was skipped
  });

  it('an item spanning sender time (t − span, t] is due when its start plays', () => {
    const b = new JitterBuffer<string>({ adaptive: false, initialDelayMs: 100 });
    b.push(1, 1000, 1030, 'a', 50); // offset 30: start 950 plays at local 1080
    expect(b.pop(1079.9)).toBeUndefined();
    expect(b.pop(1080)?.item).toBe('a');
  });

  it('playFrom: a buffered item is due at once, the ones before it dropped, the ones after at their own pace, slewing back to the delay', () => {
    const b = new JitterBuffer<number>({ adaptive: false, initialDelayMs: 100 });
    for (const seq of [1, 2, 3, 4]) b.push(seq, seq * 50, seq * 50 + 20, seq); // offset 20: t plays at t + 120
    expect(b.pop(169)).toBeUndefined(); // seq 1 is due at 170, seq 3 at 270
    expect(b.playFrom(9, 169)).toBe(false); // not buffered
    expect(b.playFrom(3, 169)).toBe(true);
    expect(b.pop(169)?.seq).toBe(3);
    // Seq 4 is 50 ms of sender time later; the clock then runs 10 % slow to win its delay back
    // (the slew): due 56 ms later, not at once and not 100 ms later.
    expect(b.pop(169 + 55)).toBeUndefined();
    expect(b.pop(169 + 56)?.seq).toBe(4);
    expect(b.stats.released).toBe(2);
  });

  it('adapts the delay to the measured jitter: ~span + p95 jitter + margin; the playout clock stays within ±10% of real time', () => {
    const rand = seededRandom(42);
    const run = (jitterMs: number) => {
      const b = new JitterBuffer<number>();
      let late = 0;
      let maxSlew = 0;
      let lastPlayout = NaN;
      let lastNow = 0;
      const arrivals: [number, number][] = [];
      for (let seq = 1; seq <= 400; seq++) arrivals.push([seq, seq * 50 + 35 + rand() * jitterMs]); // 20 Hz, 35 ms base latency
      arrivals.sort((x, y) => x[1] - y[1]);
      let i = 0;
      // A 60 Hz local frame loop pushes what arrived and pops what is due.
      for (let now = 0; now < 401 * 50 + 1000; now += 1000 / 60) {
        while (i < arrivals.length && arrivals[i][1] <= now) {
          const [seq, at] = arrivals[i++];
          b.push(seq, seq * 50, at, seq, 50);
        }
        // The playout clock never runs more than 10% off real time (no jump, no freeze).
        const playout = b.playoutTime(now);
        if (Number.isFinite(lastPlayout)) maxSlew = Math.max(maxSlew, Math.abs((playout - lastPlayout) / (now - lastNow) - 1));
        lastPlayout = playout;
        lastNow = now;
        for (let r = b.pop(now); r; r = b.pop(now)) if (r.missingBefore) late += r.missingBefore;
      }
      return { delay: b.delayMs, jitter: b.jitterMs, late, maxSlew, missing: b.stats.missing, stats: b.stats };
    };
    const calm = run(5);
    const rough = run(80);
    console.log(`jitter 0–5 ms → delay ${calm.delay.toFixed(1)} ms; jitter 0–80 ms → delay ${rough.delay.toFixed(1)} ms (p95 ${rough.jitter.toFixed(1)})`);
    // Calm: 50 ms span + ≤ 5 ms jitter + 10 ms margin.
    expect(calm.delay).toBeGreaterThan(55);
    expect(calm.delay).toBeLessThan(70);
    // Rough: 50 + ~76 + 10.
    expect(rough.delay).toBeGreaterThan(120);
    expect(rough.delay).toBeLessThan(145);
    expect(calm.maxSlew).toBeLessThanOrEqual(0.1 + 1e-9);
    expect(rough.maxSlew).toBeLessThanOrEqual(0.1 + 1e-9);
    // Everything arrived in time to play: nothing skipped, in either.
    expect(calm.missing).toBe(0);
    expect(rough.missing).toBe(0);
    expect(rough.stats.released).toBe(400);
  });

  it('refuses invalid input and holds at most `capacity` items', () => {
    const b = new JitterBuffer<number>({ capacity: 4 });
    expect(b.push(0, 0, 0, 0)).toBe('invalid');
    expect(b.push(1.5, 0, 0, 0)).toBe('invalid');
    expect(b.push(1, NaN, 0, 0)).toBe('invalid');
    expect(b.push(1, 0, Infinity, 0)).toBe('invalid');
    expect(b.push(1, 0, 0, 0, -5)).toBe('invalid');
    for (let s = 1; s <= 4; s++) expect(b.push(s, s, s, s)).toBe('ok');
    expect(b.push(5, 5, 5, 5)).toBe('overflow');
    expect(b.size).toBe(4);
  });
});
