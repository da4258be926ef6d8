/**
 * `RoomPanel`: what a page needs to put its person in a shared room, in one object. It joins the
 * room named by the page URL's `room` parameter at once; otherwise its "Share this room" button
 * makes a new unguessable room (128 random bits, `createRoomId`), puts it in the page URL and
 * joins. Either way it shows the room's link with a Copy button and a QR code (the `uqr`
 * package, drawn as an image: nothing in the URL can become markup), the connection status and
 * who is there. Call `update(dt)` once a frame after the local character's update.
 *
 * URL parameters it reads: `room=<22 base64url characters>` and `name=<shown to the others>`.
 */
import { renderSVG } from 'uqr';
import { errorMessage } from '../fetch.ts';
import { MAX_NAME_BYTES, createRoomId, isRoomId } from './protocol.ts';
import { RoomSession, type RoomSessionOptions } from './room-session.ts';

export interface RoomPanelOptions extends Omit<RoomSessionOptions, 'roomId' | 'name'> {
  /** Shown to the others; default the page URL's `name`, else "Guest" and four random digits. */
  name?: string;
  /**
   * Where the panel goes: default `document.body`, a small box in the bottom-left corner; given a
   * parent (a page's toolbar), it flows inline there and covers nothing.
   */
  parent?: HTMLElement;
  /** The page URL (default `location.href`). */
  pageUrl?: string;
}

/** The room id in a page URL's `room` parameter; null when there is none or it is not a canonical 128-bit id. */
export function roomIdFromUrl(pageUrl: string): string | null {
  const id = new URL(pageUrl).searchParams.get('room');
  return id !== null && isRoomId(id) ? id : null;
}

/** The page URL with `room=<id>` set (other parameters kept). */
export function roomUrl(id: string, pageUrl: string): string {
  const url = new URL(pageUrl);
  url.searchParams.set('room', id);
  url.hash = '';
  return url.href;
}

/** A QR code of `text` as a data: URL of an SVG image. */
export function qrCodeImage(text: string): string {
  return `data:image/svg+xml,${encodeURIComponent(renderSVG(text, { border: 2 }))}`;
}

/** A name the protocol takes: no control characters, at most 48 UTF-8 bytes. */
function cleanName(name: string): string {
  // eslint-disable-next-line no-control-regex
  let s = name.replace(/[\u0000-\u001f\u007f-\u009f\u202a-\u202e\u2066-\u2069]/g, '').trim();
  while (new TextEncoder().encode(s).length > MAX_NAME_BYTES) s = s.slice(0, -1);
  return s || 'Guest';
}

// The box lets clicks through to the page (its text must not cover a page's controls); its
// buttons and link take them.
const BOX = 'position:fixed;left:10px;bottom:10px;z-index:20;max-width:300px;pointer-events:none;padding:8px 10px;font:13px/1.4 system-ui,sans-serif;color:#e6e9ee;background:rgba(20,23,28,.86);border-radius:6px';
const INLINE = 'display:inline-block;flex:none;vertical-align:middle;max-width:300px';
const BUTTON = 'pointer-events:auto;font:inherit;color:#fff;background:#2f5fb3;border:1px solid #5b8de0;border-radius:4px;padding:3px 10px;cursor:pointer';

export class RoomPanel {
  /** The room session once joined (null before). */
  session: RoomSession | null = null;
  readonly element: HTMLDivElement;
  readonly name: string;
  private readonly o: RoomPanelOptions;
  /** The room last asked for (a join waiting on the whole database goes on only if still wanted). */
  private joining = '';
  private readonly share: HTMLButtonElement;
  private readonly details: HTMLDivElement;
  private readonly status: HTMLDivElement;

  constructor(options: RoomPanelOptions) {
    this.o = options;
    const pageUrl = options.pageUrl ?? location.href;
    this.name = cleanName(options.name ?? new URL(pageUrl).searchParams.get('name') ?? `Guest ${String(Math.floor(Math.random() * 10000)).padStart(4, '0')}`);
    this.element = Object.assign(document.createElement('div'), { className: 'mm-room-panel' });
    this.element.style.cssText = options.parent ? INLINE : BOX;
    this.share = Object.assign(document.createElement('button'), { type: 'button', textContent: 'Share this room', className: 'mm-room-share' });
    this.share.style.cssText = BUTTON;
    this.details = document.createElement('div');
    this.details.hidden = true;
    this.status = Object.assign(document.createElement('div'), { className: 'mm-room-status' });
    this.element.append(this.share, this.status, this.details);
    if (options.parent) options.parent.prepend(this.element);
    else document.body.append(this.element);
    this.share.addEventListener('click', () => {
      if (this.session) this.details.hidden = !this.details.hidden;
      else this.join(createRoomId(), true);
    });
    const id = roomIdFromUrl(pageUrl);
    if (id) this.join(id);
    else if (new URL(pageUrl).searchParams.has('room')) this.say('The link\'s room id is not valid (22 characters expected): "Share this room" makes a new room.');
  }

  /**
   * Joins room `id` (leaving the one joined before). Its link and QR code show when `showLink`
   * (a room just made, to be shared), else behind the "Room link" button: a page opened from a
   * link keeps its controls uncovered.
   */
  join(id: string, showLink = false): void {
    this.session?.close();
    this.session = null;
    this.joining = id;
    if (this.o.character.database.wholeUrl) {
      // A first part: the others replay this person on the whole database, so join on it.
      this.say('Joining once the whole database has loaded…');
      const go = () => this.joining === id && this.join(id, showLink);
      void this.o.character.whole().then(go, (e: unknown) => this.say(`Cannot join the room: ${errorMessage(e)}`));
      return;
    }
    const pageUrl = this.o.pageUrl ?? location.href;
    const link = roomUrl(id, pageUrl);
    if (!this.o.pageUrl && link !== location.href) history.replaceState(history.state, '', link);
    try {
      this.session = new RoomSession({ ...this.o, roomId: id, name: this.name, onMembers: () => (this.showMembers(), this.o.onMembers?.()) });
    } catch (e) {
      this.say(`Cannot join the room: ${errorMessage(e)}`);
      return;
    }
    this.session.client.on('status', () => this.showMembers());
    this.share.textContent = 'Room link';
    this.showLink(link, showLink);
    this.showMembers();
  }

  /** Once a frame, after the local character's update. */
  update(dt: number): void {
    this.session?.update(dt);
  }

  /** Leaves the room and removes the panel. */
  dispose(): void {
    this.session?.close();
    this.session = null;
    this.joining = '';
    this.element.remove();
  }

  private showLink(link: string, show: boolean): void {
    const a = Object.assign(document.createElement('a'), { href: link, textContent: link, className: 'mm-room-link' });
    a.style.cssText = 'pointer-events:auto;display:block;word-break:break-all;color:#9cc2ff;margin:4px 0';
    const copy = Object.assign(document.createElement('button'), { type: 'button', textContent: 'Copy link' });
    copy.style.cssText = BUTTON;
    copy.addEventListener('click', () => {
      navigator.clipboard?.writeText(link).then(
        () => (copy.textContent = 'Copied'),
        () => (copy.textContent = 'Select the link to copy it'),
      );
    });
    const qr = Object.assign(document.createElement('img'), { src: qrCodeImage(link), alt: `QR code of ${link}`, className: 'mm-room-qr', width: 160, height: 160 });
    qr.style.cssText = 'display:block;margin-top:6px;image-rendering:pixelated';
    this.details.replaceChildren(a, copy, qr);
    this.details.hidden = !show;
  }

  private showMembers(): void {
    const s = this.session;
    if (!s) return;
    const names = [...s.members.values()].map((m) => m.join.name);
    this.say(`Room · ${s.status} · you (${this.name})${names.length ? ` and ${names.join(', ')}` : ', nobody else yet'}`);
  }

  private say(text: string): void {
    this.status.textContent = text;
  }
}
