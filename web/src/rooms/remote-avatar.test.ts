import { describe, expect, it } from 'vitest';
import { InputStream } from './input-stream.ts';
import { LocalAvatar } from './local-avatar.ts';
import { decodeClientMessage, encodeMove, createMoveStep, TICKS_PER_SECOND, type PathMessage, type StateMessage, type StreamMessage, type RoomTrackerPose } from './protocol.ts';
import { RemoteAvatar, RUNTIME_WAIT_MS } from './remote-avatar.ts';
import { seededRandom } from '../bench/queries.ts';
import { TestCharacter } from './testing.ts';

interface Options {
  seconds: number;
  vr?: boolean;
  /** Drop the message with this index (0-based, counting sent messages). */
  lose?: number;
  duplicates?: number;
  /** Create the receiver only at this time (s), starting from the sender's last STATE. */
  joinAt?: number;
  /** The sender takes no steps in [from, to) s (a hidden tab: its messages keep flowing). */
  pause?: [number, number];
  /** The receiver gets no frames in [from, to) s (its page is hidden) but keeps receiving. */
  receiverHidden?: [number, number];
  seed?: number;
}

/**
 * A sender (LocalAvatar on a TestCharacter) streaming through real bytes over a simulated network
 * (30–90 ms latency, reordering, duplicates) to a receiver (RemoteAvatar on another TestCharacter).
 */
function simulate(o: Options) {
  const rand = seededRandom(o.seed ?? 1);
  let senderNow = 0;
  const a = new TestCharacter();
  const stream = new InputStream(() => senderNow);
  const local = new LocalAvatar(a, stream);
  const b = new TestCharacter();
  const notes: string[] = [];
  let remote: RemoteAvatar | null = null;
  const makeRemote = () => new RemoteAvatar(b, { onNote: (n) => notes.push(n) });
  if (o.joinAt === undefined) remote = makeRemote();
  stream.queueState();
  const inFlight: { at: number; bytes: Uint8Array }[] = [];
  let sent = 0;
  let lastState: StateMessage | null = null;
  let lastPath: PathMessage | null = null;
  const send = (now: number) => {
    for (const bytes of stream.flush()) {
      const m = decodeClientMessage(bytes);
      if (m.type === 'state') lastState = m;
      if (m.type === 'path') lastPath = m;
      if (sent++ === o.lose) continue;
      const at = now + 30 + rand() * 60;
      inFlight.push({ at, bytes });
      if (rand() < (o.duplicates ?? 0)) inFlight.push({ at: at + rand() * 40, bytes });
    }
  };
  const trackers: RoomTrackerPose[] = [0, 1, 2].map(() => ({ tracked: true, fromHand: false, position: [0, 1.6, 0], rotation: [0, 0, 0, 1] }));
  // Sender: a display at 60 Hz (VR 90 Hz) with frame-time jitter; messages at 20 Hz (VR 30 Hz).
  const frameMs = o.vr ? 1000 / 90 : 1000 / 60;
  const sendMs = o.vr ? 1000 / 30 : 50;
  let nextSend = sendMs;
  let nextState = 1000;
  let recvNow = 0;
  let maxExcess = 0;
  let maxStepsPerFrame = 0;
  let prevDisplay: [number, number] | null = null;
  const displayTrace: { t: number; error: number }[] = [];
  const positionsA: { t: number; x: number; z: number }[] = [];
  let headX = 0;
  let headZ = 0;
  const receiverStep = (until: number) => {
    while (recvNow + 1000 / 60 <= until) {
      recvNow += 1000 / 60;
      if (!remote && o.joinAt !== undefined && recvNow >= o.joinAt * 1000 && lastState) {
        remote = makeRemote();
        remote.applySnapshot(lastState, lastPath);
        // Anything already in flight after that state is still delivered.
      }
      inFlight.sort((x, y) => x.at - y.at);
      while (inFlight.length && inFlight[0].at <= recvNow) {
        const { at, bytes } = inFlight.shift()!;
        if (remote) remote.receive(decodeClientMessage(bytes) as StreamMessage, at);
      }
      if (!remote) continue;
      if (o.receiverHidden && recvNow >= o.receiverHidden[0] * 1000 && recvNow < o.receiverHidden[1] * 1000) {
        prevDisplay = null;
        continue;
      }
      const sim0 = [b.rootX, b.rootZ, b.simulatedSeconds, remote.stats.gapSeconds];
      const steps0 = remote.stats.stepsApplied;
      remote.update(recvNow, 1 / 60);
      maxStepsPerFrame = Math.max(maxStepsPerFrame, remote.stats.stepsApplied - steps0);
      // What is drawn (a copy placed only by the server's snapshot is not: `shown`).
      if (remote.shown) {
        const d: [number, number] = [b.displayX, b.displayZ];
        if (prevDisplay) {
          // Never pops: the display moves no more than the steps played this frame could move
          // the character (≤ 3.5 m/s), plus the correction's own ≤ 1.5 m/s.
          const played = b.simulatedSeconds - sim0[2] - (remote.stats.gapSeconds - sim0[3]);
          const excess = Math.hypot(d[0] - prevDisplay[0], d[1] - prevDisplay[1]) - 3.5 * played;
          maxExcess = Math.max(maxExcess, excess / (1 / 60));
        }
        prevDisplay = d;
        // Error against where the sender was at the sender time now playing.
        const playout = remote.buffer.playoutTime(recvNow);
        let k = positionsA.length - 1;
        while (k > 0 && positionsA[k].t > playout) k--;
        const at = positionsA[k];
        displayTrace.push({ t: recvNow, error: Math.hypot(b.displayX - at.x, b.displayZ - at.z) });
      }
    }
  };
  while (senderNow < o.seconds * 1000) {
    const dt = (frameMs * (0.8 + 0.4 * rand()) + (rand() < 0.02 ? 20 : 0)) / 1000;
    senderNow += dt * 1000;
    const t = senderNow / 1000;
    if (o.pause && t >= o.pause[0] && t < o.pause[1]) {
      if (senderNow >= nextState) {
        stream.queueState();
        nextState += 1000;
      }
      if (senderNow >= nextSend) {
        send(senderNow);
        nextSend += sendMs;
      }
      receiverStep(senderNow);
      continue;
    }
    if (o.vr) {
      const ang = t * 0.8;
      const vx = Math.cos(ang) * 1.2;
      const vz = -Math.sin(ang) * 1.2;
      headX += vx * dt;
      headZ += vz * dt;
      trackers[0].position = [headX, 1.6 + 0.02 * Math.sin(t * 9), headZ];
      trackers[0].rotation = [0, Math.sin(ang / 2), 0, Math.cos(ang / 2)];
      trackers[1].position = [headX - 0.2, 1.0, headZ + 0.1];
      trackers[2].position = [headX + 0.2, 1.0, headZ - 0.1];
      local.setTrackers(trackers);
      local.setTracked({ headX, headZ, velocityX: vx, velocityZ: vz, yaw: ang + Math.PI / 2, body: false, hipsDrop: t > 2 && t < 3 ? 0.3 : 0, bend: t > 2.5 && t < 3.5 ? 0.6 : 0 }, 1.08, 0.2);
    } else if (t > 2 && t < 2 + dt) {
      local.setPath(new Float32Array([a.rootX + 2, a.rootZ, a.rootX + 2, a.rootZ + 2, a.rootX, a.rootZ + 2]), new Float32Array([1.4, 3.5]), false);
    } else if (t < 2 || t > 3.5) {
      const ang = t * 1.3;
      local.setMove({ moveX: Math.sin(ang), moveZ: Math.cos(ang), faceX: 1, faceZ: 0, run: t % 2 > 1, strafe: t > 4 && t < 4.5 });
    }
    local.update(dt);
    positionsA.push({ t: (stream.simTicks * 1000) / TICKS_PER_SECOND, x: a.rootX, z: a.rootZ });
    if (senderNow >= nextState) {
      stream.queueState();
      nextState += 1000;
    }
    if (senderNow >= nextSend) {
      send(senderNow);
      nextSend += sendMs;
    }
    receiverStep(senderNow);
  }
  send(senderNow);
  receiverStep(senderNow + 3000); // the sender stands still; the receiver plays everything out
  return { a, b, remote: remote!, notes, maxExcess, maxStepsPerFrame, displayTrace, sent };
}

describe('RemoteAvatar', () => {
  it('replays a desktop stream (move, path, strafe; jittery dt; reordered and duplicated delivery) to the same floats', () => {
    const r = simulate({ seconds: 6, duplicates: 0.05 });
    expect(r.b.updates).toBe(r.a.updates);
    expect(r.b.rootX).toBe(r.a.rootX); // bit-identical, not close
    expect(r.b.rootZ).toBe(r.a.rootZ);
    expect(r.b.rootYaw).toBe(r.a.rootYaw);
    expect(r.b.simulatedSeconds).toBe(r.a.simulatedSeconds);
    expect(Math.abs(r.remote.drift.offsetX) + Math.abs(r.remote.drift.offsetZ)).toBeLessThan(1e-9);
    expect(r.remote.buffer.stats.duplicates).toBeGreaterThan(0);
    expect(r.remote.buffer.stats.missing).toBe(0);
    expect(Math.hypot(r.a.rootX, r.a.rootZ)).toBeGreaterThan(1); // it went somewhere
  });

  it('replays a VR stream (tracked steps at 90 Hz, 30 messages/s) exactly, trackers interpolated', () => {
    const r = simulate({ seconds: 5, vr: true, seed: 5 });
    expect(r.b.updates).toBe(r.a.updates);
    expect(r.b.rootX).toBe(r.a.rootX);
    expect(r.b.rootZ).toBe(r.a.rootZ);
    expect(r.b.tracked).toEqual(r.a.tracked);
    expect(r.b.scale).toBe(Math.fround(1.08));
    expect(r.b.scale).toBe(r.a.scale); // the sender drives with the wire's float32 too
    expect(r.b.alpha).toBe(r.a.alpha);
    const head = r.b.trackers![0];
    expect(head.position[1]).toBeGreaterThan(1.55);
    expect(Math.hypot(head.position[0] - r.a.tracked.headX, head.position[2] - r.a.tracked.headZ)).toBeLessThan(0.01);
  });

  it('a sender that pauses (hidden tab) and resumes: still exact, nothing guessed, no fast-forward', () => {
    const r = simulate({ seconds: 6, pause: [2, 4], seed: 11 });
    expect(r.b.rootX).toBe(r.a.rootX);
    expect(r.b.rootZ).toBe(r.a.rootZ);
    expect(r.b.updates).toBe(r.a.updates);
    expect(r.remote.stats.extrapolatedSeconds + r.remote.stats.gapSeconds).toBe(0);
    expect(r.remote.stats.lostMessages).toBe(0);
    // 60 Hz sender steps on a 60 Hz receiver: at most a few steps in one frame, never a burst.
    expect(r.maxStepsPerFrame).toBeLessThanOrEqual(3);
    expect(r.remote.buffer.delayMs).toBeLessThan(150);
  });

  it('a receiver whose page was hidden (no frames for 10 s) starts over and shows the sender again', () => {
    const r = simulate({ seconds: 16, receiverHidden: [2, 12], seed: 13 });
    expect(r.remote.stats.resyncs).toBeGreaterThanOrEqual(1);
    expect(r.notes.some((n) => /buffer full/.test(n))).toBe(true);
    const back = r.displayTrace.filter((p) => p.t > 14_000);
    expect(back.length).toBeGreaterThan(60);
    for (const p of back) expect(p.error).toBeLessThan(0.02);
    expect(r.displayTrace.at(-1)!.error).toBeLessThan(0.0015);
  });

  it('a lost message: the gap is simulated, the display blends to the sender (no pop) and converges', () => {
    const r = simulate({ seconds: 6, lose: 40, seed: 9 });
    expect(r.notes.some((n) => /lost/.test(n))).toBe(true);
    expect(r.remote.stats.lostMessages).toBe(1);
    // Played as it passed (about one message, 50 ms), not all at once.
    expect(r.remote.stats.extrapolatedSeconds).toBeGreaterThan(0.02);
    expect(r.remote.stats.extrapolatedSeconds).toBeLessThan(0.12);
    expect(r.b.rootX).not.toBe(r.a.rootX); // replay diverged…
    const final = r.displayTrace.at(-1)!.error;
    // …the display did not: within the report's 1 mm quantization (≤ 0.7 mm on each side).
    expect(final).toBeLessThan(0.0015);
    expect(r.maxExcess).toBeLessThanOrEqual(1.5 + 1e-6); // m/s beyond the character's own motion
  });

  it('late join from a snapshot, a sender without runtime state: hidden while it may come, then starts at the sender, converges within 2 s, never pops', () => {
    const r = simulate({ seconds: 7, joinAt: 2.6, seed: 3 });
    expect(r.remote.ready).toBe(true);
    expect(r.b.updates).toBeLessThan(r.a.updates);
    const joinedAt = r.displayTrace[0].t;
    // Plain STATEs (one a second here) place the copy but do not show it until RUNTIME_WAIT_MS of
    // sender time has passed since the snapshot (at most a STATE interval older than the join).
    expect(joinedAt).toBeGreaterThanOrEqual(2600 + RUNTIME_WAIT_MS - 1000);
    expect(joinedAt).toBeLessThan(2600 + RUNTIME_WAIT_MS + 1500);
    const after2s = r.displayTrace.filter((p) => p.t > joinedAt + 2000);
    expect(after2s.length).toBeGreaterThan(60);
    for (const p of after2s) expect(p.error).toBeLessThan(0.02);
    expect(r.displayTrace.at(-1)!.error).toBeLessThan(0.001);
    expect(r.maxExcess).toBeLessThanOrEqual(1.5 + 1e-6);
  });

  it('a copy placed by the snapshot is shown the moment its sender\'s state arrives, not a playout delay later', () => {
    let now = 0;
    const a = new TestCharacter();
    const stream = new InputStream(() => now);
    const local = new LocalAvatar(a, stream);
    const b = new TestCharacter();
    const remote = new RemoteAvatar(b);
    let snapshot: StateMessage | null = null;
    const deliver = () => {
      for (const bytes of stream.flush()) {
        const m = decodeClientMessage(bytes) as StreamMessage;
        if (m.type === 'state' && !snapshot) snapshot = m;
        else if (snapshot) expect(remote.receive(m, now + 40)).toBe('ok');
      }
    };
    stream.queueState();
    for (let f = 0; f < 120; f++) {
      now += 1000 / 60;
      local.setMove({ moveX: 0, moveZ: 1, faceX: 0, faceZ: 1, run: false, strafe: false });
      local.update(1 / 60);
      if (f === 30) {
        deliver(); // the server's cached snapshot: the first STATE
        remote.applySnapshot(snapshot!, null);
      }
      if (f % 3 === 2) deliver();
      remote.update(now + 40, 1 / 60);
    }
    expect(remote.ready).toBe(true);
    expect(remote.shown).toBe(false); // placed, waiting for the sender's state
    // The sender answers the newcomer (a restart here: TestCharacter has no runtime bytes).
    stream.queueState(true);
    deliver();
    remote.update(now + 40, 1 / 60); // the frame it arrived in
    expect(remote.shown).toBe(true);
    expect(remote.exact).toBe(true);
  });

  it('refuses untrusted positions with a note and never drives the character with them', () => {
    const b = new TestCharacter();
    const notes: string[] = [];
    const remote = new RemoteAvatar(b, { onNote: (n) => notes.push(n) });
    const far = decodeClientMessage(encodeMove({ seq: 1, time: 50, rootX: 2_000_000, rootZ: 0, rootYaw: 0, steps: [{ ...createMoveStep(), ticks: 120 }] })) as StreamMessage;
    expect(remote.receive(far, 0)).toBe('invalid');
    remote.update(10_000, 1 / 60);
    expect(b.updates).toBe(0);
    expect(notes[0]).toMatch(/beyond/);
    expect(remote.stats.refused).toBe(1);
  });
});
