/**
 * Whether this page's WebGL draws in software (SwiftShader, llvmpipe, WARP: a blocklisted or
 * absent GPU, a VM, a remote desktop, a headless test browser). Multisampling there is paid per
 * sample on the CPU: the demo at 320×240 on SwiftShader draws 17.5 frames/s with MSAA and 37.9
 * without, and three pages in one room (three skinned avatars each) 2 frames/s each against 6 —
 * so renderers drop MSAA and draw at one pixel per CSS pixel there, and keep both on a real GPU.
 *
 * `failIfMajorPerformanceCaveat` would be the standard test, but Chromium started with
 * `--enable-unsafe-swiftshader` does not report it; the unmasked renderer string does. The
 * answer must be known before the page's first context exists (MSAA is fixed at creation), so
 * the first visit probes a throwaway canvas (about 13 ms on SwiftShader, its context released)
 * and remembers the answer in `localStorage`; later visits take it from there, and every
 * renderer made checks it against its own context (`rememberRenderer`), so a machine that
 * changed (a GPU blocklisted since) is right again from its next page.
 */
let software: boolean | undefined;

const SOFTWARE = /swiftshader|llvmpipe|softpipe|lavapipe|software|basic render|warp/i;
const KEY = 'mm-avatar:software-webgl';

function stored(): boolean | undefined {
  try {
    const v = globalThis.localStorage?.getItem(KEY);
    return v === '1' ? true : v === '0' ? false : undefined;
  } catch {
    return undefined; // storage refused (sandboxed frame, privacy settings): probe
  }
}

/** What `gl` says; undefined when it says nothing (a lost context answers null). */
function rendererIsSoftware(gl: WebGLRenderingContext | WebGL2RenderingContext): boolean | undefined {
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const name = gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER);
  return typeof name === 'string' && name !== '' ? SOFTWARE.test(name) : undefined;
}

/** Remembers `truth` for this page's later renderers and the next page. */
function remember(truth: boolean): void {
  software = truth;
  try {
    if (stored() !== truth) globalThis.localStorage?.setItem(KEY, truth ? '1' : '0');
  } catch {
    /* storage refused: the next page probes again */
  }
}

export function softwareWebGL(): boolean {
  if (software !== undefined) return software;
  software = stored();
  if (software !== undefined) return software;
  software = false;
  if (typeof document === 'undefined') return software;
  const gl = document.createElement('canvas').getContext('webgl2') ?? document.createElement('canvas').getContext('webgl');
  if (!gl) return software;
  remember(rendererIsSoftware(gl) ?? false);
  gl.getExtension('WEBGL_lose_context')?.loseContext();
  return software;
}

/** Checks the answer against a renderer's own context (one that names no renderer changes nothing). */
export function rememberRenderer(gl: WebGLRenderingContext | WebGL2RenderingContext): void {
  const truth = rendererIsSoftware(gl);
  if (truth !== undefined) remember(truth);
}
