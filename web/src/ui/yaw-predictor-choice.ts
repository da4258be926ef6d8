import { errorMessage } from '../fetch.ts';
import type { BodyYawPredictor } from '../vr/body-yaw.ts';
import { type NetworkYawPredictor, loadNetworkPredictor } from '../vr/network-yaw.ts';
import type { TrackedDrive } from '../vr/tracked-drive.ts';

export interface YawPredictorChoiceOptions {
  /** The orientation model's URL, and the recurrent model's (null: none). */
  model: string;
  recurrentModel: string | URL | null;
  /** What drives once the network has loaded: 'network', or 'heuristic' to keep the heuristic. */
  prefer: string;
  /** The choice (options `heuristic` and `network`) and the line that says which drives and why. */
  select: HTMLSelectElement;
  status: HTMLElement;
  /** Called after each change, e.g. for the page's test hook. */
  onChange?: (choice: YawPredictorChoice) => void;
}

/**
 * The VR page's body-yaw predictor: the heuristic until the orientation network has loaded
 * (`load()`), the network then, the heuristic for good if it cannot load (its option disabled);
 * a `<select>` switches, and a status line says which drives and why (the model's URL, or why it
 * did not load, in its title) — or that the tracked body does (`showBody`), the predictor standing by.
 */
export class YawPredictorChoice {
  /** The network, once loaded. */
  network: NetworkYawPredictor | null = null;
  /** Why the network did not load (the heuristic drives for good), or null. */
  fallback: string | null = null;
  private loading: Promise<void> | null = null;
  private body = false;

  constructor(
    private readonly drive: TrackedDrive,
    private readonly heuristic: BodyYawPredictor,
    private readonly options: YawPredictorChoiceOptions,
  ) {
    options.select.addEventListener('change', () => this.choose(options.select.value));
    this.show();
  }

  /** Loads the network, once (the same promise after); resolves either way. */
  load(): Promise<void> {
    const { model, recurrentModel, prefer, select } = this.options;
    this.loading ??= loadNetworkPredictor(model, { recurrentModel }).then(
      (network) => {
        this.network = network;
        this.choose(prefer === 'heuristic' ? 'heuristic' : 'network');
      },
      (e: unknown) => {
        console.warn((this.fallback = `orientation model unavailable (${model}): ${errorMessage(e)}`));
        (select.querySelector('option[value="network"]') as HTMLOptionElement).disabled = true;
        this.show();
      },
    );
    return this.loading;
  }

  /** Drives with the network (`'network'`, once loaded) or the heuristic. */
  choose(name: string): void {
    this.drive.setPredictor(name === 'network' && this.network ? this.network : this.heuristic);
    this.show();
  }

  /** Whether the tracked body drives the yaw now (body tracking); the status says so. Call every frame: it redraws on a change only. */
  showBody(tracked: boolean): void {
    if (tracked === this.body) return;
    this.body = tracked;
    this.show();
  }

  private show(): void {
    const { select, status, model } = this.options;
    const name = this.drive.predictor.name;
    select.value = name === 'network' ? 'network' : 'heuristic';
    const failed = this.fallback !== null;
    const waiting = failed
      ? 'fallback: heuristic — the orientation model did not load'
      : 'body yaw: heuristic (loading the network…)';
    status.textContent = this.body ? 'body yaw: tracked hips' : this.network ? `body yaw: ${name}` : waiting;
    status.title = this.fallback ?? `model: ${model}`;
    status.classList.toggle('fallback', failed);
    this.options.onChange?.(this);
  }
}
