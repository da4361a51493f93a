// Open the viewer in headless Chromium (Debian's, driven by playwright-core) against a running
// service, watch a live herd for a while, and print what happened as JSON: chunks, frames,
// pixels the herd covers, console errors, first-animal time, client frame time, stalls.
//   node js/browser/viewer-run.js --url http://127.0.0.1:8000 --chromium /usr/bin/chromium \
//        --herd 1000 --seconds 20 [--animal horse] [--screenshot docs/viewer.png] [--query '&terrain=hills']
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { parseArgs } from 'node:util';
import { chromium } from 'playwright-core';

const { values: opt } = parseArgs({ options: {
  url: { type: 'string' }, chromium: { type: 'string', default: '/usr/bin/chromium' },
  herd: { type: 'string', default: '200' }, seconds: { type: 'string', default: '10' },
  animal: { type: 'string', default: 'horse' }, screenshot: { type: 'string' },
  query: { type: 'string' }, width: { type: 'string', default: '1280' }, height: { type: 'string', default: '720' },
} });

// This machine's flags: no sandbox (root in a container), software GL, nothing phoning home.
const FLAGS = ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
  '--disable-background-networking', '--disable-component-update', '--disable-sync'];

const profile = mkdtempSync(join(tmpdir(), 'quadsynth-chromium-'));
const context = await chromium.launchPersistentContext(profile, {
  executablePath: opt.chromium, headless: true, args: FLAGS,
  viewport: { width: Number(opt.width), height: Number(opt.height) },
});
const result = { herd: Number(opt.herd), animal: opt.animal, consoleErrors: [], samples: [] };
try {
  const page = context.pages()[0] ?? await context.newPage();
  page.on('console', (m) => { if (m.type() === 'error') result.consoleErrors.push(`${m.text()} (${m.location().url})`); });
  page.on('pageerror', (e) => result.consoleErrors.push(String(e)));
  page.on('requestfailed', (r) => result.consoleErrors.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
  await page.goto(`${opt.url}/viewer?animal=${opt.animal}&herd=${opt.herd}${opt.query ?? ''}`, { waitUntil: 'load' });
  await page.waitForFunction(() => window.quadsynthViewer?.firstDrawMs !== null || window.quadsynthViewer?.errors.length,
    null, { timeout: 60000 });
  const end = Date.now() + Number(opt.seconds) * 1000;
  while (Date.now() < end) {
    await page.waitForTimeout(1000);
    const s = await page.evaluate(() => ({ ...window.quadsynthViewer }));
    result.samples.push({ t: Date.now(), chunks: s.chunks, frames: s.frames, aheadS: s.aheadS, stalls: s.stalls,
      stalledS: s.stalledS, frameMs: s.frameMs, renderFps: s.renderFps, latencyS: s.latencyS });
  }
  const s = await page.evaluate(() => ({ ...window.quadsynthViewer, pixels: window.quadsynthViewer.herdPixels(),
    terrainFeet: window.quadsynthViewer.terrainFeet?.() ?? null }));
  Object.assign(result, {
    openMs: s.openMs, startMs: s.startMs, leadSentMs: s.leadSentMs, firstChunkMs: s.firstChunkMs, firstDrawMs: s.firstDrawMs, chunks: s.chunks, frames: s.frames,
    pixels: s.pixels, mode: s.mode, errors: s.errors, reconnects: s.reconnects, stalls: s.stalls,
    stalledS: s.stalledS, renderFps: s.renderFps, frameMs: s.frameMs, frameMsP95: s.frameMsP95,
    latencyS: s.latencyS, aheadS: s.aheadS, drawn: s.drawn, arrivals: s.arrivals, streamFps: s.streamFps,
    terrain: s.terrain ?? null, terrainFeet: s.terrainFeet,
  });
  if (opt.screenshot) await page.screenshot({ path: opt.screenshot });
} finally {
  await context.close();
  rmSync(profile, { recursive: true, force: true });
}
console.log(JSON.stringify(result));
