/**
 * The first module of the one-tag build to run (register.ts imports it before the element):
 * when the page has an `<mm-avatar>` that will use the shipped core, first part or avatar, their
 * reads from the library's cache (cache.ts) begin here, before three.js and the library evaluate
 * and the element builds its renderer — ~50-70 ms of main thread during which the reads used to
 * wait to be asked for, and then for the browser's cache. A module script runs after the page is
 * parsed, so the elements are there to be looked at. What nobody takes is let go (cache.ts).
 */
import { DEFAULT_AVATAR, DEFAULT_FIRST_PART, assetUrl } from '../assets.ts';
import { readEarly } from '../cache.ts';

if (typeof document !== 'undefined') {
  const elements = [...document.querySelectorAll('mm-avatar')];
  if (elements.length > 0) readEarly(assetUrl('mmcore_bg.wasm').href);
  if (elements.some((e) => !e.hasAttribute('database'))) readEarly(assetUrl(DEFAULT_FIRST_PART).href);
  if (elements.some((e) => !e.hasAttribute('avatar'))) readEarly(assetUrl(DEFAULT_AVATAR).href);
}
