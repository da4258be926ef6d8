/**
 * Bytes per second of one avatar's stream, measured by encoding a synthetic session with the
 * real sender (`InputStream`) and counting WebSocket framing (RFC 6455: 2-byte header, 4 more
 * for 126+ byte payloads, a 4-byte mask client → server) and the 3-byte relay prefix the server
 * adds. TCP/IP headers are not counted (they depend on how the OS coalesces segments).
 */
import { InputStream } from './input-stream.ts';
import { createMoveStep, websocketFrameOverhead, type RoomTrackerPose } from './protocol.ts';

export interface BandwidthOptions {
  mode: 'desktop' | 'vr';
  /** The sender's display rate (simulation steps a second). */
  frameHz: number;
  /** Messages a second. */
  sendHz: number;
  seconds: number;
  /** Desktop: the move direction changes every frame (camera orbiting); VR: always moving. */
  changeEveryFrame: boolean;
  /** STATE messages a second (default 1). */
  stateHz?: number;
}

export interface BandwidthResult {
  mode: string;
  frameHz: number;
  sendHz: number;
  messagesPerSecond: number;
  meanPayloadBytes: number;
  /** Sender → server, with framing and mask. */
  upBytesPerSecond: number;
  /** Server → each receiver, with the relay prefix and framing. */
  downBytesPerSecond: number;
}

export function measureBandwidth(o: BandwidthOptions): BandwidthResult {
  let clockMs = 0;
  const stream = new InputStream(() => clockMs);
  const stateHz = o.stateHz ?? 1;
  let up = 0;
  let down = 0;
  let messages = 0;
  let payload = 0;
  const send = (bytes: Uint8Array[]) => {
    for (const b of bytes) {
      messages++;
      payload += b.length;
      up += b.length + websocketFrameOverhead(b.length, true);
      down += b.length + 3 + websocketFrameOverhead(b.length + 3, false);
    }
  };
  const frames = Math.round(o.seconds * o.frameHz);
  let nextSend = 0;
  let nextState = 0;
  const step = createMoveStep();
  const trackers: RoomTrackerPose[] = [0, 1, 2].map(() => ({ tracked: true, fromHand: false, position: [0, 0, 0], rotation: [0, 0, 0, 1] }));
  let x = 0;
  let z = 0;
  for (let f = 0; f < frames; f++) {
    const t = f / o.frameHz;
    const dt = 1 / o.frameHz;
    clockMs = t * 1000;
    const a = o.changeEveryFrame ? t * 0.7 : 0;
    if (o.mode === 'desktop') {
      step.ticks = stream.clock.ticksFor(dt);
      step.moveX = Math.sin(a);
      step.moveZ = Math.cos(a);
      step.faceX = Math.sin(a);
      step.faceZ = Math.cos(a);
      step.run = false;
      stream.recordMove(step);
      x += step.moveX * 1.4 * dt;
      z += step.moveZ * 1.4 * dt;
    } else {
      x = Math.sin(a) * 2;
      z = Math.cos(a) * 2;
      const yaw = a + Math.PI / 2;
      trackers[0].position = [x, 1.6 + 0.02 * Math.sin(t * 11), z];
      trackers[0].rotation = [0, Math.sin(yaw / 2), 0, Math.cos(yaw / 2)];
      trackers[1].position = [x - 0.3 * Math.cos(yaw), 1.0 + 0.1 * Math.sin(t * 5), z + 0.3 * Math.sin(yaw)];
      trackers[1].rotation = [Math.sin(t) * 0.3, 0.2, 0.1, 0.93];
      trackers[2].position = [x + 0.3 * Math.cos(yaw), 1.0 - 0.1 * Math.sin(t * 5), z - 0.3 * Math.sin(yaw)];
      trackers[2].rotation = [-Math.sin(t) * 0.3, -0.2, 0.1, 0.93];
      stream.setTrackers(trackers);
      stream.recordTracked({ ticks: stream.clock.ticksFor(dt), headX: x, headZ: z, velocityX: 1.4 * Math.cos(a), velocityZ: -1.4 * Math.sin(a), yaw, body: false, hipsDrop: 0.02, bend: 0 });
    }
    stream.report(x, z, a, f);
    if (t >= nextState) {
      stream.queueState();
      nextState += 1 / stateHz;
    }
    if (t + dt >= nextSend) {
      send(stream.flush());
      nextSend += 1 / o.sendHz;
    }
  }
  send(stream.flush());
  return {
    mode: `${o.mode}${o.changeEveryFrame ? '' : ' (steady input)'}`,
    frameHz: o.frameHz,
    sendHz: o.sendHz,
    messagesPerSecond: Math.round(messages / o.seconds),
    meanPayloadBytes: Math.round(payload / messages),
    upBytesPerSecond: Math.round(up / o.seconds),
    downBytesPerSecond: Math.round(down / o.seconds),
  };
}
