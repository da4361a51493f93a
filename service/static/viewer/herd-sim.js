// A small crowd simulation in the page: a herd keeping formation around a leader that goes round
// a big loop, through every gait's speed in turn. It makes the live points the viewer streams.

function rng(seed) { // mulberry32: seeded, so a herd of a given size looks the same on every load
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = Math.imul(a ^ (a >>> 15), 1 | a);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

export class HerdSim {
  /**
   * @param count   animals
   * @param gaits   the library's gaits [{name, min_speed, max_speed}] (GET /v1/libraries/{animal})
   * @param spacing metres between neighbours in the formation
   */
  constructor(count, gaits, { fps = 30, spacing = 3, seed = 1 } = {}) {
    this.C = count; this.fps = fps; this.time = 0;
    const random = rng(seed);
    // Hold each moving gait's middle speed for 6 s, with a stand at the start of every round.
    const moving = gaits.filter((g) => g.max_speed > 0.05).sort((a, b) => a.max_speed - b.max_speed);
    this.profile = [{ speed: 0, seconds: 3 }, ...moving.map((g) => ({ speed: 0.5 * (g.min_speed + g.max_speed), seconds: 6 })),
      ...moving.slice(0, -1).reverse().map((g) => ({ speed: 0.5 * (g.min_speed + g.max_speed), seconds: 4 }))];
    this.period = this.profile.reduce((t, p) => t + p.seconds, 0);
    const side = Math.ceil(Math.sqrt(count));
    this.radius = Math.max(30, side * spacing * 2);
    this.leader = { angle: 0, speed: 0 };
    this.slot = new Float32Array(count * 2); // formation offsets (side, back), metres
    this.pos = new Float32Array(count * 2);
    this.heading = new Float32Array(count);
    this.speed = new Float32Array(count);
    this.wander = new Float32Array(count);
    for (let c = 0; c < count; c++) {
      const row = Math.floor(c / side), col = c % side;
      this.slot[c * 2] = (col - (side - 1) / 2 + (random() - 0.5) * 0.6) * spacing;
      this.slot[c * 2 + 1] = (row + (random() - 0.5) * 0.6) * spacing;
      this.wander[c] = random() * Math.PI * 2;
      const [x, z] = this.slotPosition(c);
      this.pos[c * 2] = x; this.pos[c * 2 + 1] = z;
      this.heading[c] = this.leaderHeading();
    }
  }

  leaderHeading() { return this.leader.angle + Math.PI / 2; } // tangent of the loop, counter-clockwise

  /** Where animal c belongs now: its slot behind and beside the leader. */
  slotPosition(c) {
    const h = this.leaderHeading(), fx = Math.sin(h), fz = Math.cos(h);
    const side = this.slot[c * 2], back = this.slot[c * 2 + 1];
    const lx = this.radius * Math.cos(this.leader.angle), lz = -this.radius * Math.sin(this.leader.angle);
    return [lx - fx * back + fz * side, lz - fz * back - fx * side];
  }

  targetSpeed(t) {
    let s = t % this.period;
    for (const p of this.profile) { if (s < p.seconds) return p.speed; s -= p.seconds; }
    return 0;
  }

  /** The next `n` points of every animal: Float32Array (C, n, 3), metres, Y up. */
  step(n) {
    const C = this.C, dt = 1 / this.fps, out = new Float32Array(C * n * 3);
    for (let f = 0; f < n; f++) {
      this.time += dt;
      const want = this.targetSpeed(this.time);
      this.leader.speed += Math.max(-2 * dt, Math.min(2 * dt, want - this.leader.speed)); // 2 m/s^2
      this.leader.angle += (this.leader.speed * dt) / this.radius;
      for (let c = 0; c < C; c++) {
        const [tx, tz] = this.slotPosition(c);
        const x = this.pos[c * 2], z = this.pos[c * 2 + 1];
        // Steer to the slot: heading towards it, speed to close the gap within ~2 s.
        const dx = tx - x, dz = tz - z, gap = Math.hypot(dx, dz);
        const sway = 0.15 * Math.sin(this.time * 0.5 + this.wander[c]);
        let speed = Math.min(this.leader.speed * 1.25 + 0.6, this.leader.speed + gap / 2);
        if (gap < 0.05 && this.leader.speed < 0.05) speed = 0;
        const aim = gap > 0.05 ? Math.atan2(dx, dz) + sway * Math.min(speed, 1) : this.heading[c];
        let turn = aim - this.heading[c];
        turn = Math.atan2(Math.sin(turn), Math.cos(turn));
        this.heading[c] += Math.max(-1.5 * dt, Math.min(1.5 * dt, turn)); // 1.5 rad/s at most
        this.speed[c] += Math.max(-3 * dt, Math.min(3 * dt, speed - this.speed[c]));
        this.pos[c * 2] = x + Math.sin(this.heading[c]) * this.speed[c] * dt;
        this.pos[c * 2 + 1] = z + Math.cos(this.heading[c]) * this.speed[c] * dt;
        const o = (c * n + f) * 3;
        out[o] = this.pos[c * 2]; out[o + 1] = 0; out[o + 2] = this.pos[c * 2 + 1];
      }
    }
    return out;
  }
}
