/**
 * What a loading page or element tells its user: each stage (`core`, `database`, `avatar`, …)
 * with its URL and bytes, which ones are done, what a stalled download is waiting for, and a
 * failure with a Retry button. `<mm-avatar>` shows it inside the element; the pages show it in
 * their toolbar (`LoadingStatus.attach`).
 */
import type { FetchProgress } from '../fetch.ts';

const mb = (n: number) => (n >= 1e5 ? `${(n / 1e6).toFixed(1)} MB` : `${Math.max(0, Math.round(n / 1e3))} kB`);

/** A URL as a person reads it: the path on this origin (its `?v=` version dropped), else in full. */
export function shortUrl(url: string): string {
  try {
    const u = new URL(url, typeof location !== 'undefined' ? location.href : undefined);
    u.searchParams.delete('v');
    const same = typeof location !== 'undefined' && u.origin === location.origin;
    return same ? `${u.pathname}${u.search}` : u.href;
  } catch {
    return url;
  }
}

/** One line per stage: `database /databases/locomotion.mmdb 3.2 / 8.9 MB`, `… 0.3 MB ✓`. */
export function describeProgress(p: FetchProgress): string {
  const size = p.done ? `${mb(p.loaded)} ✓${p.cached ? ' (cached)' : ''}` : p.total ? `${mb(p.loaded)} / ${mb(p.total)}` : p.loaded ? mb(p.loaded) : 'waiting for the server';
  return `${p.stage} ${shortUrl(p.url)} ${size}`;
}

export class LoadingStatus {
  private readonly stages = new Map<string, FetchProgress>();
  private error: string | null = null;
  private note: string | null = null;

  /**
   * @param render called with the text to show (null: hide), whether it is an error, and a
   *   retry callback when the failure offers one.
   */
  constructor(private readonly render: (text: string | null, state: 'loading' | 'stalled' | 'error' | 'note', retry: (() => void) | null) => void) {}

  /** Progress of one download (fetch.ts `onProgress`). */
  update = (p: FetchProgress): void => {
    this.stages.set(p.stage, { ...p });
    this.show();
  };

  /** A line before any download starts ("Waiting to come into view…"). */
  say(text: string | null): void {
    this.note = text;
    this.error = null;
    this.show();
  }

  /** A failure; `retry` puts a Retry button beside it. */
  fail(message: string, retry: (() => void) | null = null): void {
    this.error = message;
    this.render(message, 'error', retry);
  }

  /** Everything loaded: hide, or keep `note` visible (an avatar that fell back). */
  finish(note: string | null = null): void {
    this.stages.clear();
    this.error = null;
    this.note = note;
    this.render(note, 'note', null);
  }

  reset(): void {
    this.stages.clear();
    this.error = null;
    this.note = null;
  }

  /** The stalled stage, if any. */
  get stalled(): FetchProgress | null {
    for (const p of this.stages.values()) if (p.stalled && !p.done) return p;
    return null;
  }

  private show(): void {
    if (this.error) return;
    const stalled = this.stalled;
    if (stalled) {
      const got = stalled.loaded ? ` (${mb(stalled.loaded)}${stalled.total ? ` of ${mb(stalled.total)}` : ''} so far)` : '';
      this.render(`Still waiting for the ${stalled.stage} ${shortUrl(stalled.url)}: nothing received for 5 s${got}. Slow or stalled connection; it keeps trying.`, 'stalled', null);
      return;
    }
    const lines = [...this.stages.values()].map(describeProgress);
    this.render(lines.length ? `Loading · ${lines.join(' · ')}` : this.note, 'loading', null);
  }

  /**
   * A status shown in a page element (the pages' toolbar): text, an error style, and a Retry
   * button when a failure offers one.
   */
  static attach(element: HTMLElement): LoadingStatus {
    return new LoadingStatus((text, state, retry) => {
      element.hidden = text === null;
      element.textContent = text ?? '';
      element.dataset.state = state;
      element.title = text ?? '';
      if (retry) {
        const button = document.createElement('button');
        button.type = 'button';
        button.className = 'retry';
        button.textContent = 'Retry';
        button.addEventListener('click', () => retry());
        element.append(' ', button);
      }
    });
  }
}
