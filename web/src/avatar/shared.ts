/**
 * One load of a model for everyone on the page who shows it. `<mm-avatar>` elements and
 * `Character.create()` calls asking for the same avatar URL share one download, one parse and
 * one set of geometries, materials and textures: the first asker gets the loaded avatar, later
 * ones a clone of it (`Avatar.clone`: nothing parsed or built again). Each `Avatar.load` of the
 * shipped avatar is ~0.1 s of main thread here (glTF parse, meshopt decode, roles, culling), so
 * a page of ten characters spent a second on copies of the same file.
 *
 * A VRM is loaded for each asker (its extras are per instance). A failed load is forgotten, so
 * asking again (a Retry) loads again; so is a model whose every user has been disposed.
 */
import type { FetchOptions, FetchProgress } from '../fetch.ts';
import { Avatar, type AvatarOptions } from './avatar.ts';

interface Entry {
  readonly loaded: Promise<Avatar>;
  /** The askers' progress callbacks while the one download runs. */
  readonly listeners: Set<(p: FetchProgress) => void>;
  /** Whether the loaded avatar itself was handed out (later askers get clones). */
  taken: boolean;
  /** The loaded avatar, once loaded. */
  avatar?: Avatar;
}

const entries = new Map<string, Entry>();

/**
 * `Avatar.load(url, options)`, shared with every other asker of the same URL (and name and
 * role overrides) on the page. `signal` aborts this asker's wait, not the download the others
 * share; progress reaches every asker while it runs.
 */
export async function loadSharedAvatar(url: string | URL, options: AvatarOptions & FetchOptions = {}): Promise<Avatar> {
  const { signal, onProgress, ...rest } = options;
  const href = new URL(String(url), typeof location !== 'undefined' ? location.href : undefined).href;
  const key = JSON.stringify([href, rest.name ?? null, rest.roles ?? null]);
  // Models nobody shows any more are let go (their memory with them), this one included.
  for (const [k, e] of entries) if (e.avatar && !e.avatar.inUse) entries.delete(k);
  let entry = entries.get(key);
  if (!entry) {
    const listeners = new Set<(p: FetchProgress) => void>();
    const loaded = Avatar.load(href, { ...rest, onProgress: (p) => listeners.forEach((l) => l(p)) });
    const created: Entry = { loaded, listeners, taken: false };
    entries.set(key, created);
    loaded.then(
      (a) => (created.avatar = a),
      () => entries.get(key) === created && entries.delete(key),
    );
    entry = created;
  }
  if (onProgress) entry.listeners.add(onProgress);
  try {
    const avatar = await abortable(entry.loaded, signal);
    if (!entry.taken) {
      entry.taken = true;
      return avatar;
    }
    return avatar.vrm ? await Avatar.load(href, options) : avatar.clone();
  } finally {
    if (onProgress) entry.listeners.delete(onProgress);
  }
}

/** `promise`, or its rejection with `signal`'s reason as soon as that aborts. */
function abortable<T>(promise: Promise<T>, signal: AbortSignal | undefined): Promise<T> {
  if (!signal) return promise;
  if (signal.aborted) return Promise.reject(signal.reason);
  return new Promise<T>((resolve, reject) => {
    const onAbort = () => reject(signal.reason);
    signal.addEventListener('abort', onAbort, { once: true });
    promise.then(
      (v) => (signal.removeEventListener('abort', onAbort), resolve(v)),
      (e: unknown) => (signal.removeEventListener('abort', onAbort), reject(e)),
    );
  });
}
