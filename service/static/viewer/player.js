// The play-out buffer: chunks in as they arrive, one frame out per display tick at the stream's
// fps. Poses come in bursts (a segment at a time), so playback runs a little behind the newest
// frame; when it catches up with it, it holds the last frame and counts the stall.

export class Player {
  constructor(fps) {
    this.fps = fps;
    this.chunks = []; // in frame order
    this.end = 0; // frames received: [0, end)
    this.playhead = 0; // frames, fractional
    this.started = false;
    this.stalledSeconds = 0;
    this.stalls = 0;
    this.chunksIn = 0;
  }

  add(chunk) {
    if (chunk.start !== this.end) throw new Error(`chunk starts at frame ${chunk.start}, expected ${this.end}`);
    this.chunks.push(chunk);
    this.end = chunk.start + chunk.frames;
    this.chunksIn += 1;
  }

  /** Advance the clock by `dt` seconds; the frame to show now, or null before the first chunk. */
  advance(dt) {
    if (!this.chunks.length) return null;
    if (this.started) {
      const next = this.playhead + dt * this.fps;
      if (next > this.end - 1) {
        if (this.playhead < this.end - 1) this.stalls += 1;
        this.stalledSeconds += (next - (this.end - 1)) / this.fps;
      }
      this.playhead = Math.min(next, this.end - 1);
    }
    this.started = true;
    const f = Math.floor(this.playhead);
    while (this.chunks.length > 1 && this.chunks[0].start + this.chunks[0].frames <= f) this.chunks.shift();
    const chunk = this.chunks.find((c) => f < c.start + c.frames);
    const i = f - chunk.start, n = chunk.frames, J = chunk.joints;
    return {
      frame: f, root: chunk.root, rotations: chunk.rotations, gait: chunk.gait,
      rootAt: (c) => (c * n + i) * 3, rotAt: (c) => (c * n + i) * J * 4, gaitAt: (c) => c * n + i,
    };
  }

  /** Seconds of frames received beyond the one shown. */
  get ahead() { return (this.end - 1 - this.playhead) / this.fps; }
}
