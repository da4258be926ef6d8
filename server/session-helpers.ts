/**
 * Test helper: a person in a room as a page is one — a `Character` (VR: the VR settings, α and a
 * 1.07× taller person, as `TrackedDrive` sets it up and calibrates) and a `RoomSession` on a real
 * room server reached over a `ws` socket with the server's origin. Shared by the single-process
 * (`web/src/rooms/room-session.test.ts`) and the multi-process (`multi-process-exact.test.ts`) tests.
 */
import * as THREE from 'three';
import { WebSocket } from 'ws';
import { Character } from '../web/src/character/character.ts';
import type { Database } from '../web/src/core/database.ts';
import type { WebSocketLike } from '../web/src/rooms/room-client.ts';
import { RoomSession } from '../web/src/rooms/room-session.ts';
import { DEFAULT_ALPHA, VR_SETTINGS } from '../web/src/vr/tracked-drive.ts';

export interface SessionPerson {
  character: Character;
  session: RoomSession;
  /** What the session told its page (replay notes, errors). */
  notes: string[];
}

/** Joins `roomId` on `server` as `name`, in `mode`, with a character on `db` (no avatar). */
export function sessionPerson(db: Database, server: { url(roomId: string): string; origin: string }, roomId: string, mode: 'desktop' | 'vr', name: string): SessionPerson {
  const character = new Character(db, null);
  if (mode === 'vr') {
    character.settings = VR_SETTINGS;
    character.object3d.scale.setScalar(1.07);
    character.setAlpha(DEFAULT_ALPHA);
  }
  const notes: string[] = [];
  const session = new RoomSession({
    roomId,
    character,
    scene: new THREE.Group(),
    mode,
    name,
    builtinAvatars: [null],
    trace: true,
    onNote: (n) => notes.push(n),
    client: {
      url: server.url(roomId),
      baseUrl: `${server.origin}/index.html`,
      createSocket: (url) => new WebSocket(url, { origin: server.origin }) as unknown as WebSocketLike,
    },
  });
  return { character, session, notes };
}
