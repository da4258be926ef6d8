import { errorMessage } from '../fetch.ts';
import { showError } from './error-box.ts';

type Report = (message: string) => void;

/**
 * A page's error report: each message is added to the page's test hook (`hook.error`, one line
 * each) and shown (`show`, default the error box); the window's uncaught errors and unhandled
 * rejections are reported too, as `error: …`. Returns the report function.
 */
export function catchPageErrors(hook: { error: string | null }, show: Report = showError): Report {
  const fail = (message: string) => {
    hook.error = hook.error ? `${hook.error}\n${message}` : message;
    show(message);
  };
  window.addEventListener('error', (e) => fail(`error: ${e.message}`));
  window.addEventListener('unhandledrejection', (e) => fail(`error: ${errorMessage(e.reason)}`));
  return fail;
}
