/** Zero-copy typed views of WASM memory that survive memory growth. */

/**
 * Typed views over WASM memory are invalidated when the memory grows (the old ArrayBuffer is
 * detached). `ViewCache` recreates a view only when the buffer or pointer changed.
 */
export class ViewCache<T extends Float32Array | Uint8Array> {
  private view: T | null = null;
  private buffer: ArrayBufferLike | null = null;
  private ptr = -1;

  constructor(
    private readonly Ctor: { new (buffer: ArrayBufferLike, byteOffset: number, length: number): T },
    private readonly length: number,
  ) {}

  get(memory: WebAssembly.Memory, ptr: number): T {
    const buffer = memory.buffer;
    if (this.view === null || this.buffer !== buffer || this.ptr !== ptr) {
      this.view = new this.Ctor(buffer, ptr, this.length);
      this.buffer = buffer;
      this.ptr = ptr;
    }
    return this.view;
  }
}
