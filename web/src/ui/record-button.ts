import { type RecordingMeta, TrackerRecorder, encodeRecordingJson } from '../vr/recording.ts';
import type { TrackerSample } from '../vr/tracker-sample.ts';
import { saveTextFile } from './save-file.ts';

/**
 * The VR page's Record button: a click starts recording the tracker samples (`add`, each
 * frame), the next click stops and offers the recording as a file to save
 * (`vr-session-<time>.json`, replayable with `vr.html?replay=URL`).
 */
export class RecordButton {
  private readonly recorder = new TrackerRecorder();
  private recording = false;

  /** `meta`: what the recording says about itself, asked for when it stops. */
  constructor(
    private readonly button: HTMLButtonElement,
    private readonly meta: () => RecordingMeta,
  ) {
    button.addEventListener('click', () => {
      if (!this.recording) return this.start();
      const text = this.stop();
      if (text) saveTextFile(text, `vr-session-${new Date().toISOString().replace(/[:.]/g, '-')}.json`);
    });
  }

  /** Starts afresh. */
  start(): void {
    this.recorder.clear();
    this.recording = true;
    this.button.textContent = 'Stop recording';
  }

  /** Stops; the recording as JSON ('' when no frame was recorded). */
  stop(): string {
    [this.recording, this.button.textContent] = [false, 'Record'];
    return this.recorder.frames === 0 ? '' : encodeRecordingJson(this.recorder.toRecording(this.meta()));
  }

  /** Records this frame's sample while recording. */
  add(sample: TrackerSample): void {
    if (this.recording) this.recorder.add(sample);
  }
}
