/**
 * Loading a character for a page, the way `<mm-avatar>` does it: the core, the database and the
 * avatar in parallel, each stage shown with its URL and bytes (`LoadingStatus`), a stalled
 * download named after 5 s, a failed database shown with a Retry button, a failed avatar
 * replaced by the skeleton with a note. Pages that build their own scene (the VR page) use it.
 */
import { Avatar } from '../avatar/avatar.ts';
import { loadSharedAvatar } from '../avatar/shared.ts';
import { Character } from '../character/character.ts';
import { type Database, loadDatabase } from '../core/database.ts';
import { errorMessage, mark } from '../fetch.ts';
import type { LoadingStatus } from './loading-status.ts';

export interface PageCharacterOptions {
  database: string | URL;
  /** GLB/VRM URL; null: the skeleton. */
  avatar: string | URL | null;
  status: LoadingStatus;
  /** What Retry does after a failed database; default: reload the page. */
  retry?: () => void;
}

export interface PageCharacter {
  character: Character;
  /** Why the avatar is not shown (it failed and the skeleton stands in), or null. */
  avatarNote: string | null;
}

/** Loads and builds the character; resolves null when the database failed (the status says why, with Retry). */
export async function loadPageCharacter(options: PageCharacterOptions): Promise<PageCharacter | null> {
  const { status } = options;
  const databaseUrl = String(options.database);
  // One load per model on the page, as the element's (a room's members who show it get clones).
  const avatarLoad = options.avatar ? loadSharedAvatar(options.avatar, { onProgress: status.update }).catch((e: unknown) => e as Error) : Promise.resolve(null);
  let database: Database;
  try {
    database = await loadDatabase(databaseUrl, { onProgress: status.update });
  } catch (e) {
    status.fail(errorMessage(e), options.retry ?? (() => location.reload()));
    const a = await avatarLoad;
    if (a instanceof Avatar) a.dispose();
    return null;
  }
  const a = await avatarLoad;
  const avatar = a instanceof Avatar ? a : null;
  const avatarNote = a && !(a instanceof Avatar) ? `Avatar unavailable, showing the skeleton: ${errorMessage(a)}` : null;
  try {
    const character = new Character(database, avatar);
    mark('mm:character-ready'); // load benchmarks print each step (scripts/bench-load.mjs)
    return { character, avatarNote };
  } finally {
    database.release(); // the character holds its own reference
  }
}
