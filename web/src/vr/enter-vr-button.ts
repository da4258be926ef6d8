/**
 * The Enter-VR button: requests an `immersive-vr` session with `local-floor` (docs/method.md §9:
 * trackers are read in the floor-level space) and hands it to three.js. Unlike three's VRButton
 * it exposes `enter()`/`exit()` for the test hook and says why VR is unavailable (Quest Browser
 * allows WebXR only on secure origins: HTTPS or localhost).
 */
import type * as THREE from 'three';

export const SESSION_INIT: XRSessionInit = {
  requiredFeatures: ['local-floor'],
  optionalFeatures: ['bounded-floor', 'hand-tracking', 'body-tracking'],
};

export class EnterVrButton {
  readonly element: HTMLButtonElement;
  private session: XRSession | null = null;

  constructor(
    private readonly renderer: THREE.WebGLRenderer,
    private readonly onError: (message: string) => void,
  ) {
    this.element = document.createElement('button');
    this.element.id = 'enter-vr';
    this.element.type = 'button';
    this.element.disabled = true;
    this.element.textContent = 'checking VR…';
    this.element.addEventListener('click', () => {
      (this.session ? this.exit() : this.enter()).catch((e: unknown) => this.onError(`VR: ${e instanceof Error ? e.message : String(e)}`));
    });
  }

  /** Checks support; resolves to whether immersive VR can be entered. */
  async init(): Promise<boolean> {
    if (!navigator.xr) {
      this.element.textContent = window.isSecureContext ? 'VR not available' : 'VR needs HTTPS';
      this.element.title = window.isSecureContext ? 'This browser has no WebXR (try ?emulate=1)' : 'WebXR needs a secure origin: run `npm start -- --https`';
      return false;
    }
    const supported = await navigator.xr.isSessionSupported('immersive-vr').catch(() => false);
    this.element.textContent = supported ? 'Enter VR' : 'VR not supported';
    this.element.disabled = !supported;
    return supported;
  }

  get active(): boolean {
    return this.session !== null;
  }

  async enter(): Promise<void> {
    if (this.session || !navigator.xr) return;
    const session = await navigator.xr.requestSession('immersive-vr', SESSION_INIT);
    session.addEventListener('end', () => {
      this.session = null;
      this.element.textContent = 'Enter VR';
    });
    this.renderer.xr.setReferenceSpaceType('local-floor');
    await this.renderer.xr.setSession(session);
    this.session = session;
    this.element.textContent = 'Exit VR';
  }

  async exit(): Promise<void> {
    await this.session?.end();
  }
}
