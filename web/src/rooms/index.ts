/**
 * Shared rooms, client side (docs/rooms.md). The wire protocol, the connection, the sending
 * stream and the replay of remote members on any `DrivenCharacter` are engine-free (no three.js,
 * no WASM: the room server and the load test use them in Node); `RoomCharacter`, `RoomSession`,
 * `RoomPanel` and `NameLabel` put them on the engine's `Character` and a three.js scene.
 */
export * from './protocol.ts';
export { InputStream, TickClock, type StreamReport } from './input-stream.ts';
export { RoomClient, type RoomClientEvents, type RoomClientOptions, type RoomStatus, type WebSocketLike } from './room-client.ts';
export { JitterBuffer, type JitterBufferOptions, type JitterStats, type PushResult, type Released } from './jitter-buffer.ts';
export { DriftCorrector, type DriftCorrectorOptions } from './drift-corrector.ts';
export { type DrivenCharacter, type PathInput } from './driven-character.ts';
export { LocalAvatar } from './local-avatar.ts';
export { RemoteAvatar, type RemoteAvatarOptions, type RemoteAvatarStats } from './remote-avatar.ts';
export { measureBandwidth, type BandwidthOptions, type BandwidthResult } from './bandwidth.ts';
export { RoomCharacter } from './room-character.ts';
export { RoomSession, type RoomMember, type RoomMemberView, type RoomNote, type RoomSessionOptions } from './room-session.ts';
export { roomOf } from './room-of.ts';
export { RoomPanel, qrCodeImage, roomIdFromUrl, roomUrl, type RoomPanelOptions } from './room-panel.ts';
export { NameLabel } from './name-label.ts';
