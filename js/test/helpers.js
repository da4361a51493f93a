// Shared by the tests: paths to synthesize and the services to ask (started by
// tests/test_js_client.py, which passes their URLs).
import WebSocket from 'ws';
import { QuadSynthClient } from '../src/index.js';

export const URL = process.env.QUADSYNTH_URL;
export const FLAKY_URL = process.env.QUADSYNTH_FLAKY_URL; // ws_window 1, ws_send_timeout_s 1

// Node 20 has no WebSocket of its own; chunks of big herds pass ws' 100 MiB default.
const webSocket = (url) => new WebSocket(url, { perMessageDeflate: false, maxPayload: 0 });

export function client(url = URL, options = {}) {
  return new QuadSynthClient(url, { webSocket, ...options });
}

/** C characters, F points at `fps`: each starts still, speeds up to its own pace (walk to
 * canter), and curves; metres, Y up, flat ground. Returns Float32Array (C, F, 3). */
export function herd(C, F, fps = 60) {
  const out = new Float32Array(C * F * 3);
  for (let c = 0; c < C; c++) {
    let x = 4 * c, z = 0, heading = 0.3 * c;
    const top = 1.5 + 1.5 * (c % 4); // m/s: walk to canter
    for (let f = 0; f < F; f++) {
      const t = f / fps;
      const speed = top * Math.min(Math.max(t - 0.5, 0) / 2, 1);
      heading += 0.15 / fps;
      x += Math.sin(heading) * speed / fps; z += Math.cos(heading) * speed / fps;
      out.set([x, 0, z], (c * F + f) * 3);
    }
  }
  return out;
}

/** The request characters of a herd (C, F, 3). */
export function characters(points, C) {
  const F = points.length / (3 * C);
  return Array.from({ length: C }, (_, c) => ({ id: `h${c}`, points: points.subarray(c * F * 3, (c + 1) * F * 3) }));
}

/** Angle between rotations a[i..i+4) and b[j..j+4), degrees (q and -q are one rotation). */
export function angleDeg(a, i, b, j) {
  // 2 atan2(|v|, |w|) of conj(a) b: exact near 0, where acos(dot) is not
  const w = a[i] * b[j] + a[i + 1] * b[j + 1] + a[i + 2] * b[j + 2] + a[i + 3] * b[j + 3];
  const vx = a[i + 3] * b[j] - b[j + 3] * a[i] - (a[i + 1] * b[j + 2] - a[i + 2] * b[j + 1]);
  const vy = a[i + 3] * b[j + 1] - b[j + 3] * a[i + 1] - (a[i + 2] * b[j] - a[i] * b[j + 2]);
  const vz = a[i + 3] * b[j + 2] - b[j + 3] * a[i + 2] - (a[i] * b[j + 1] - a[i + 1] * b[j]);
  return (2 * Math.atan2(Math.hypot(vx, vy, vz), Math.abs(w)) * 180) / Math.PI;
}
