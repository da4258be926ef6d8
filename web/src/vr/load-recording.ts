/**
 * `loadRecording(url)`: a tracker recording from a URL (JSON as `Record` saves it), or the
 * built-in scripted motion for `'scripted'` (72 Hz).
 */
import { fetchBytes } from '../fetch.ts';
import { type Recording, TrackerRecorder, decodeRecording } from './recording.ts';
import { SCRIPT_DURATION, scriptedSample } from './scripted-motion.ts';
import { TrackerSample } from './tracker-sample.ts';

export async function loadRecording(url: string): Promise<Recording> {
  if (url !== 'scripted') return decodeRecording(await fetchBytes(url, { stage: 'recording' }), url);
  const recorder = new TrackerRecorder(Math.ceil(SCRIPT_DURATION * 72) + 2);
  const s = new TrackerSample();
  for (let f = 0; f / 72 <= SCRIPT_DURATION; f++) recorder.add((scriptedSample(f / 72, s), s));
  return recorder.toRecording({ source: 'scripted-motion', rate: 72 });
}
