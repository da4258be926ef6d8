/**
 * The standalone build's entry (`dist/mm-avatar.js`): registers `<mm-avatar>` on load, so a
 * plain page needs one `<script type="module" src=".../mm-avatar.js">`. Bundler users import
 * `defineMMAvatar` from the package (or `mm-avatar/element`, this file).
 */
import { defineMMAvatar } from './mm-avatar.ts';

defineMMAvatar();

export { MMAvatarElement, defineMMAvatar } from './mm-avatar.ts';
export { liveObjects } from '../core/wasm.ts';
