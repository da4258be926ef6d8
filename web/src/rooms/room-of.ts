/**
 * Which room a character is in: `RoomSession` registers itself for its local character, so a
 * page that has only the character or the `<mm-avatar>` element (`el.room`) can reach the room's
 * public view without a global. Kept apart from `RoomSession` so the element does not bundle the
 * room code to ask.
 */
import type { RoomSession } from './room-session.ts';

const sessions = new WeakMap<object, RoomSession>();

/** The room session `character` is in (its person's own character), or null. */
export function roomOf(character: object | null | undefined): RoomSession | null {
  return (character && sessions.get(character)) || null;
}

/** Called by `RoomSession` (join: the session; close: null). */
export function setRoomOf(character: object, session: RoomSession | null): void {
  if (session) sessions.set(character, session);
  else sessions.delete(character);
}
