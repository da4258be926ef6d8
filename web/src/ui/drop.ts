/**
 * Files dropped on the page, sorted by what they are for: BVH takes (build a database in the
 * page), a database (`.mmdb`), or an avatar (`.glb`, `.vrm`). Anything else is reported, not
 * silently ignored.
 */

export interface DroppedFiles {
  bvh: File[];
  databases: File[];
  avatars: File[];
  /** Names of files of no known kind. */
  unknown: string[];
}

export function sortDroppedFiles(files: Iterable<File>): DroppedFiles {
  const out: DroppedFiles = { bvh: [], databases: [], avatars: [], unknown: [] };
  for (const f of files) {
    const ext = f.name.toLowerCase().match(/\.([a-z0-9]+)$/)?.[1] ?? '';
    if (ext === 'bvh') out.bvh.push(f);
    else if (ext === 'mmdb') out.databases.push(f);
    else if (ext === 'glb' || ext === 'vrm') out.avatars.push(f);
    else out.unknown.push(f.name);
  }
  return out;
}

/**
 * Calls `onDrop` with the files dropped anywhere on `target`, showing `overlay` while files are
 * dragged over it.
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
    if (files && files.length > 0) onDrop(sortDroppedFiles(files));
  });
}
