/**
 * `mm-avatar/element` and the standalone build's entry (`dist/mm-avatar.js`): registers
 * `<mm-avatar>` on load in a browser, so a plain page needs one
 * `<script type="module" src=".../mm-avatar.js">` and a bundled app one
 * `import 'mm-avatar/element'`. Outside a browser (server-side rendering, Node tests) importing it
 * registers nothing and touches no DOM global.
 */
import { defineMMAvatar } from './mm-avatar.ts';

defineMMAvatar();

export { MMAvatarElement, defineMMAvatar } from './mm-avatar.ts';
export { liveObjects } from '../core/wasm.ts';
