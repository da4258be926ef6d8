/**
 * Files dropped on the page, sorted by what they are for: motion (BVH takes, VRM Animation
 * `.vrma`, glTF/GLB files with animations and no mesh: build a database in the page), a database
 * (`.mmdb`), or an avatar (`.vrm`, and `.glb`/`.gltf` with a mesh). Anything else is reported, not
 * silently ignored. `droppedDatabase`: the database they make.
 */
import { DatabaseBuilder } from '../core/builder.ts';
import { Database } from '../core/database.ts';

export interface DroppedFiles {
  /** Motion to build a database from (`DatabaseBuilder.addFile`): BVH, VRMA, animation-only glTF/GLB. */
  motions: File[];
  databases: File[];
  avatars: File[];
  /** Names of files of no known kind. */
  unknown: string[];
}

/** Whether a glTF/GLB file holds animations and no mesh (motion, not an avatar), from its JSON. */
async function isMotionOnly(file: File): Promise<boolean> {
  try {
    const head = new Uint8Array(await file.slice(0, 20).arrayBuffer());
    let text: string;
    if (new TextDecoder().decode(head.subarray(0, 4)) === 'glTF') {
      const length = new DataView(head.buffer).getUint32(12, true);
      text = new TextDecoder().decode(await file.slice(20, 20 + length).arrayBuffer());
    } else text = await file.text();
    const json = JSON.parse(text) as { animations?: unknown[]; meshes?: unknown[] };
    return (json.animations?.length ?? 0) > 0 && (json.meshes?.length ?? 0) === 0;
  } catch {
    return false; // not readable as glTF: the avatar loader says what is wrong with it
  }
}

export async function sortDroppedFiles(files: Iterable<File>): Promise<DroppedFiles> {
  const out: DroppedFiles = { motions: [], databases: [], avatars: [], unknown: [] };
  for (const f of files) {
    const ext = f.name.toLowerCase().match(/\.([a-z0-9]+)$/)?.[1] ?? '';
    if (ext === 'bvh' || ext === 'vrma') out.motions.push(f);
    else if (ext === 'mmdb') out.databases.push(f);
    else if (ext === 'glb' || ext === 'gltf') (await isMotionOnly(f) ? out.motions : out.avatars).push(f);
    else if (ext === 'vrm') out.avatars.push(f);
    else out.unknown.push(f.name);
  }
  return out;
}

/**
 * Calls `onDrop` with the files dropped anywhere on `target`, sorted, showing `overlay` while
 * files are dragged over it.
 */
export function installDropTarget(target: HTMLElement, overlay: HTMLElement, onDrop: (files: DroppedFiles) => void): void {
  let depth = 0; // dragenter/dragleave fire for every child crossed
  const hasFiles = (e: DragEvent) => e.dataTransfer?.types.includes('Files') ?? false;
  target.addEventListener('dragenter', (e) => {
    if (!hasFiles(e)) return;
    depth++;
    overlay.hidden = false;
  });
  target.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) overlay.hidden = true;
  });
  target.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    if (e.dataTransfer) e.dataTransfer.dropEffect = 'copy';
  });
  target.addEventListener('drop', (e) => {
    e.preventDefault();
    depth = 0;
    overlay.hidden = true;
    const files = e.dataTransfer?.files;
    if (files && files.length > 0) void sortDroppedFiles([...files]).then(onDrop);
  });
}

/**
 * The database dropped files make: one built from the motion files (`DatabaseBuilder`), named
 * after the first and how many more; else the first `.mmdb`; null with neither. Throws what is
 * wrong, naming the file.
 */
export async function droppedDatabase(files: DroppedFiles): Promise<Database | null> {
  const read = async (f: File) => new Uint8Array(await f.arrayBuffer());
  const { motions, databases } = files;
  let bytes: Uint8Array;
  let name: string;
  if (motions.length) {
    const builder = new DatabaseBuilder({});
    try {
      for (const f of motions) builder.addFile(f.name, await read(f));
      bytes = builder.build();
      name = motions.length === 1 ? motions[0].name : `${motions[0].name} + ${motions.length - 1} more`;
    } finally {
      builder.free();
    }
  } else if (databases.length) [bytes, name] = [await read(databases[0]), databases[0].name];
  else return null;
  return Database.fromBytes(bytes, name);
}
