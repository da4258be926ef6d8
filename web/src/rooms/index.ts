/**
 * Shared rooms, client side (docs/rooms.md): the wire protocol, the connection, the sending
 * stream, and the replay of remote members on any `DrivenCharacter`. Browser-safe; no three.js,
 * no WASM.
 */
export * from './protocol.ts';
export { InputStream, TickClock } from './input-stream.ts';
export { RoomClient, type RoomClientEvents, type RoomClientOptions, type RoomStatus, type WebSocketLike } from './room-client.ts';
export { JitterBuffer, type JitterBufferOptions, type JitterStats, type PushResult, type Released } from './jitter-buffer.ts';
export { DriftCorrector, type DriftCorrectorOptions } from './drift-corrector.ts';
export { type DrivenCharacter, type PathInput } from './driven-character.ts';
export { LocalAvatar, type MoveInputLike } from './local-avatar.ts';
export { RemoteAvatar, type RemoteAvatarOptions, type RemoteAvatarStats } from './remote-avatar.ts';
export { measureBandwidth, type BandwidthOptions, type BandwidthResult } from './bandwidth.ts';
