/** `window.__viewer`: the viewer's state for end-to-end tests, kept up to date every frame. */
export interface ViewerHook {
  /** Frames in the loaded database (0 until loaded). */
  numFrames: number;
  frame: number;
  playing: boolean;
  clipName: string;
  /** Message shown in the error box, or null. */
  error: string | null;
  /** True once the database is loaded and the first frame drawn. */
  ready: boolean;
}

declare global {
  interface Window {
    __viewer: ViewerHook;
  }
}

export function installViewerHook(): ViewerHook {
  const hook: ViewerHook = { numFrames: 0, frame: 0, playing: false, clipName: '', error: null, ready: false };
  window.__viewer = hook;
  return hook;
}
