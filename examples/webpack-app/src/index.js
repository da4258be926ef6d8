// One import registers <mm-avatar>; the element loads the shipped database and avatar, which
// webpack found through the package's `new URL('…', import.meta.url)` references and emitted
// into dist/ with the WASM core.
import 'mm-avatar/element';

const el = document.getElementById('avatar');
el.addEventListener('error', (e) => console.warn(`mm-avatar: ${e.detail.message}`));
