/** The load test's short variant (CI): 20 clients in 4 rooms for 3 s, through scripts/rooms-load.mjs. */
import { execFile } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { expect, it } from 'vitest';

it('load test, short: every message relayed, no errors, bytes per avatar within targets', async () => {
  const dir = mkdtempSync(join(tmpdir(), 'rooms-load-test-'));
  const out = join(dir, 'report.json');
  try {
    await new Promise<void>((resolve, reject) => {
      execFile(process.execPath, ['scripts/rooms-load.mjs', '--clients', '20', '--rooms', '4', '--seconds', '3', '--json', out], { timeout: 60_000 }, (error, stdout) => {
        if (error) reject(error);
        else {
          console.log(stdout.split('\n').slice(0, 12).join('\n'));
          resolve();
        }
      });
    });
    const r = JSON.parse(readFileSync(out, 'utf8'));
    expect(r.server.internalErrors).toBe(0);
    expect(r.clientErrors).toBe(0);
    expect(r.closedEarly).toBe(0);
    expect(r.server.dropped).toEqual({});
    // 20 members sending ~24 messages/s, each relayed to the 4 others of its room, for 3 s.
    expect(r.latencySamples).toBeGreaterThan(20 * 20 * 4 * 3 * 0.8);
    expect(r.latencyMs.p50).toBeLessThan(100); // loopback; generous for a busy 2-core machine
    expect(r.desktop.downBytesPerSecondPerReceiver).toBeLessThanOrEqual(2048);
    expect(r.vr.downBytesPerSecondPerReceiver).toBeLessThanOrEqual(4096);
    expect(r.desktop.downBytesPerSecondPerReceiver).toBeGreaterThan(500);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
}, 90_000);
