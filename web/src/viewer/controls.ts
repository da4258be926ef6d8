/** The toolbar: play/pause button, frame scrubber and HUD text, bound to a `Playback`. */
import type { Playback } from './playback.ts';

export class ViewerControls {
  private readonly button: HTMLButtonElement;
  private readonly scrubber: HTMLInputElement;
  private readonly hud: HTMLElement;
  private shownFrame = -1;
  private shownPlaying: boolean | null = null;
  /** True while the user holds the scrubber's thumb: playback must not move it under them. */
  private dragging = false;

  constructor(
    private readonly playback: Playback,
    /** Called after a user action moves the frame. */
    private readonly onSeek: () => void,
  ) {
    this.button = document.getElementById('play') as HTMLButtonElement;
    this.scrubber = document.getElementById('scrubber') as HTMLInputElement;
    this.hud = document.getElementById('hud') as HTMLElement;

    this.scrubber.min = '0';
    this.scrubber.max = String(Math.max(0, playback.numFrames - 1));
    this.button.addEventListener('click', () => this.toggle());
    this.scrubber.addEventListener('pointerdown', () => (this.dragging = true));
    window.addEventListener('pointerup', () => (this.dragging = false));
    this.scrubber.addEventListener('input', () => {
      playback.seek(Number(this.scrubber.value));
      onSeek();
    });
    window.addEventListener('keydown', (e) => {
      if (e.target instanceof HTMLInputElement && e.key !== ' ') return;
      if (e.key === ' ') {
        e.preventDefault();
        this.toggle();
      } else if (e.key === 'ArrowRight' || e.key === 'ArrowLeft') {
        playback.playing = false;
        playback.step(e.key === 'ArrowRight' ? 1 : -1);
        onSeek();
      }
    });
  }

  private toggle(): void {
    this.playback.toggle();
    this.onSeek();
  }

  /** Refreshes the widgets; touches the DOM only when something changed. */
  update(clipName: string): void {
    const { frame, playing, numFrames, fps } = this.playback;
    if (playing !== this.shownPlaying) {
      this.button.textContent = playing ? 'Pause' : 'Play';
      this.shownPlaying = playing;
    }
    if (frame !== this.shownFrame) {
      if (!this.dragging) this.scrubber.value = String(frame);
      this.hud.textContent = `clip ${clipName} · frame ${frame} / ${numFrames} · ${fps} fps`;
      this.shownFrame = frame;
    }
  }

  /** Forces the next `update()` to redraw (after a seek). */
  invalidate(): void {
    this.shownFrame = -1;
  }
}
