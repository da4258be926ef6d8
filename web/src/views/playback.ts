/** Frame clock: plays frames in order at the database frame rate, looping; seek and pause. */
export class Playback {
  frame = 0;
  playing = true;
  private accumulator = 0;

  constructor(
    readonly numFrames: number,
    readonly fps: number,
  ) {}

  /** Advances by `dt` seconds of real time; returns true when the frame changed. */
  update(dt: number): boolean {
    if (!this.playing || this.numFrames === 0) return false;
    // A long stall (background tab) does not fast-forward through seconds of frames.
    this.accumulator += Math.min(dt, 0.25) * this.fps;
    if (this.accumulator < 1) return false;
    const steps = Math.floor(this.accumulator);
    this.accumulator -= steps;
    this.frame = (this.frame + steps) % this.numFrames;
    return true;
  }

  seek(frame: number): void {
    this.frame = Math.min(Math.max(0, Math.round(frame)), Math.max(0, this.numFrames - 1));
    this.accumulator = 0;
  }

  step(delta: number): void {
    this.seek((this.frame + delta + this.numFrames) % this.numFrames);
  }

  toggle(): void {
    this.playing = !this.playing;
    this.accumulator = 0;
  }
}
