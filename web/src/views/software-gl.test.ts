import { afterAll, describe, expect, it } from 'vitest';
import { rememberRenderer, softwareWebGL } from './software-gl.ts';

// A renderer's context as far as the check goes: its unmasked renderer string.
const context = (name: string) =>
  ({
    RENDERER: 0x1f01,
    getExtension: (e: string) => (e === 'WEBGL_debug_renderer_info' ? { UNMASKED_RENDERER_WEBGL: 0x9246 } : null),
    getParameter: (p: number) => (p === 0x9246 ? name || null : 'WebKit WebGL'),
  }) as unknown as WebGL2RenderingContext;

const items = new Map<string, string>();
const g = globalThis as { localStorage?: unknown };
g.localStorage = { getItem: (k: string) => items.get(k) ?? null, setItem: (k: string, v: string) => void items.set(k, v) };
afterAll(() => void delete g.localStorage);

describe('softwareWebGL', () => {
  it('takes a remembered answer without probing, and a renderer\'s own context corrects it for this page and the next', () => {
    items.set('mm-avatar:software-webgl', '1');
    expect(softwareWebGL()).toBe(true); // no document here: only the stored answer can say so
    rememberRenderer(context('ANGLE (NVIDIA, NVIDIA GeForce RTX 4070 Direct3D11 vs_5_0 ps_5_0)'));
    expect(softwareWebGL()).toBe(false);
    expect(items.get('mm-avatar:software-webgl')).toBe('0');
    rememberRenderer(context('ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero)), SwiftShader driver)'));
    expect(softwareWebGL()).toBe(true);
    expect(items.get('mm-avatar:software-webgl')).toBe('1');
    rememberRenderer(context('')); // a lost context says nothing: the answer stands
    expect(softwareWebGL()).toBe(true);
    expect(items.get('mm-avatar:software-webgl')).toBe('1');
  });
});
