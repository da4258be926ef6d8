/**
 * `mm-avatar/rooms`: shared rooms — people see each other's avatars over the network
 * (docs/rooms.md). Its own entry so a desktop app that never joins a room never bundles the
 * client and the protocol.
 *
 * The wire protocol, the connection, the sending stream and the replay of remote members on any
 * `DrivenCharacter` are engine-free (no three.js, no WASM: the room server and the load test use
 * them in Node); `RoomCharacter`, `RoomSession`, `RoomPanel` and `NameLabel` put them on the
 * engine's `Character` and a three.js scene.
 *
 * ```ts
 * import { RoomSession } from 'mm-avatar/rooms';
 * ```
 *
 * @packageDocumentation
 * @module mm-avatar/rooms
 */
export { RoomCharacter } from './room-character.ts';
export { RoomSession, type RoomMember, type RoomMemberView, type RoomNote, type RoomSessionOptions } from './room-session.ts';
export { roomOf } from './room-of.ts';
export { RoomPanel, qrCodeImage, roomIdFromUrl, roomUrl, type RoomPanelOptions } from './room-panel.ts';
export { NameLabel } from './name-label.ts';
export { RoomClient, type RoomClientEvents, type RoomClientOptions, type RoomStatus, type WebSocketLike } from './room-client.ts';
export { InputStream, TickClock, type StreamReport } from './input-stream.ts';
export { JitterBuffer, type JitterBufferOptions, type JitterStats, type PushResult, type Released } from './jitter-buffer.ts';
export { DriftCorrector, type DriftCorrectorOptions } from './drift-corrector.ts';
export type { DrivenCharacter } from './driven-character.ts';
export { LocalAvatar } from './local-avatar.ts';
export { RemoteAvatar, type RemoteAvatarOptions, type RemoteAvatarStats } from './remote-avatar.ts';
export { measureBandwidth, type BandwidthOptions, type BandwidthResult } from './bandwidth.ts';
export { CloseCode, LeaveReason, PROTOCOL_VERSION, ProtocolError, TICKS_PER_SECOND, createRoomId, decodeClientMessage, decodeServerMessage, isRoomId, unbatch } from './protocol.ts';
export type { AvatarChoice, ClientMessage, DeviceMode, DeviceSet, JoinInfo, LeaveReasonName, MemberInfo, MoveMessage, MoveStep, PathMessage, RoomTrackerPose, ServerMessage, StateMessage, StreamMessage, TrackedMessage, TrackedStep } from './protocol.ts';
