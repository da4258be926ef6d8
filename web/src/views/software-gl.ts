/**
 * Whether this page's WebGL draws in software (SwiftShader, llvmpipe, WARP: a blocklisted or
 * absent GPU, a VM, a remote desktop, a headless test browser). Multisampling there is paid per
 * sample on the CPU: the demo at 320×240 on SwiftShader draws 17.5 frames/s with MSAA and 37.9
 * without, and three pages in one room (three skinned avatars each) 2 frames/s each against 6 —
 * so renderers drop MSAA and draw at one pixel per CSS pixel there, and keep both on a real GPU.
 *
 * `failIfMajorPerformanceCaveat` would be the standard test, but Chromium started with
 * `--enable-unsafe-swiftshader` does not report it; the unmasked renderer string does. Probed
 * once per page on a throwaway canvas (about 13 ms on SwiftShader), whose context is released.
 */
let software: boolean | undefined;

const SOFTWARE = /swiftshader|llvmpipe|softpipe|lavapipe|software|basic render|warp/i;

export function softwareWebGL(): boolean {
  if (software !== undefined) return software;
  software = false;
  if (typeof document === 'undefined') return software;
  const gl = document.createElement('canvas').getContext('webgl2') ?? document.createElement('canvas').getContext('webgl');
  if (!gl) return software;
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) ?? '');
  software = SOFTWARE.test(name);
  gl.getExtension('WEBGL_lose_context')?.loseContext();
  return software;
}
