/**
 * Shows errors in the page (an `#error-box` element by default), not only in the console. A
 * click on the box dismisses it.
 */
export function showError(message: string, box: HTMLElement | null = document.getElementById('error-box')): void {
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
