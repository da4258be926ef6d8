/**
 * Shows errors in the page (the `#error-box` element), not only in the console. A click on the
 * box dismisses it.
 */
export function showError(message: string): void {
  const box = document.getElementById('error-box');
  if (box) {
    box.title = 'click to dismiss';
    box.onclick = () => {
      box.hidden = true;
      box.textContent = '';
    };
    box.textContent = box.hidden || !box.textContent ? message : `${box.textContent}\n${message}`;
    box.hidden = false;
  }
}

/** The message of anything thrown (wasm-bindgen may throw strings). */
export function errorMessage(e: unknown): string {
  return e instanceof Error ? e.message : String(e);
}
