// Opens the viewer's page in headless Chromium (puppeteer-core over the system's chromium, no
// browser download) and checks it for real: the page loads the scene, connects, draws frames,
// and two screenshots taken apart differ where a tissue model lies (it deforms). Optionally
// keeps the page open for --seconds and reports frame rate and latency per hop (measure mode).
//
//   node viewer_page.mjs --modules DIR --url URL [--chromium PATH] [--screenshot FILE]
//                        [--model I] [--gap-ms MS] [--attempts N] [--seconds S] [--json FILE]
//                        [--expect-deformation M] [--screenshot-cycle C]
//                        [--expect-metrics S]  (the session panel must show the stream's trainee metrics within S s)
//                        [--fault-command CMD] [--expect-fault S]  (then a fault banner must show within S s)
//                        [--playback-seek A,B]  (a recording source: the playback bar shows; paused,
//                        a seek to A then to B changes the model's screen area, pause holds the frame)
// Exit: 0 pass, 1 fail, 77 chromium absent (ctest SKIP_RETURN_CODE).
import { createRequire } from 'node:module';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((pairs, a, i, all) => {
  if (a.startsWith('--')) pairs.push([a.slice(2), all[i + 1]]);
  return pairs;
}, []));
const chromium = args.chromium || '/usr/bin/chromium';
if (!fs.existsSync(chromium)) {
  console.log(`viewer_page: ${chromium} not found: skipped (install Debian's chromium)`);
  process.exit(77);
}
const require = createRequire(path.join(path.resolve(args.modules), 'package.json'));
const puppeteer = require('puppeteer-core');
const modelIndex = Number(args.model ?? 0);
const gapMs = Number(args['gap-ms'] ?? 500);
const seconds = Number(args.seconds ?? 0);

function fail(message) {
  console.error(`viewer_page: FAIL: ${message}`);
  process.exitCode = 1;
}

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
         '--window-size=1024,720'],
  defaultViewport: { width: 1024, height: 720 },
});
try {
  const page = await browser.newPage();
  const consoleErrors = [];
  page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
  page.on('pageerror', (e) => consoleErrors.push(String(e)));
  await page.goto(args.url, { waitUntil: 'load', timeout: 10000 });
  const minFrames = args['playback-seek'] ? 1 : 5;  // a recording's frames may be sparse
  try {
    await page.waitForFunction((minFrames) => window.viewerStats && window.viewerStats.connected &&
                               window.viewerStats.framesDrawn >= minFrames, { timeout: 10000, polling: 100 }, minFrames);
  } catch {
    const s = await page.evaluate(() => window.viewerStats);
    throw new Error(`page did not connect and draw ${minFrames} frames in 10 s: ${JSON.stringify(s && { ...s, hops: undefined, rebuildMs: undefined })}; console: ${consoleErrors.join(' | ')}`);
  }
  const rect = await page.evaluate((i) => window.viewerScreenRects()[i], modelIndex);
  if (!rect || rect.width < 10 || rect.height < 10) throw new Error(`model ${modelIndex} is not on screen: ${JSON.stringify(rect)}`);
  const clip = { x: Math.floor(rect.x), y: Math.floor(rect.y), width: Math.ceil(rect.width), height: Math.ceil(rect.height) };
  const differing = (a, b) => page.evaluate(async (a, b) => {
    const load = async (data) => {
      const image = new Image();
      image.src = `data:image/png;base64,${data}`;
      await image.decode();
      const canvas = document.createElement('canvas');
      canvas.width = image.width; canvas.height = image.height;
      const context = canvas.getContext('2d');
      context.drawImage(image, 0, 0);
      return context.getImageData(0, 0, image.width, image.height).data;
    };
    const pa = await load(a), pb = await load(b);
    let count = 0;
    for (let i = 0; i < pa.length; i += 4) {
      if (Math.abs(pa[i] - pb[i]) + Math.abs(pa[i + 1] - pb[i + 1]) + Math.abs(pa[i + 2] - pb[i + 2]) > 24) ++count;
    }
    return { count, total: pa.length / 4 };
  }, a, b);
  if (args['playback-seek']) {
    // Playback: the bar is there; pause, seek to A (the frame drawn, then held), seek to B.
    const [a, b] = args['playback-seek'].split(',').map(Number);
    const bar = await page.evaluate(() => getComputedStyle(document.getElementById('playback')).display);
    if (bar !== 'flex') throw new Error(`no playback bar (display ${bar})`);
    const seekTo = async (t) => {
      await page.evaluate((t) => window.viewerPlaybackRequest({ action: 'seek', t }), t);
      await page.waitForFunction((t) => window.viewerPlayback && window.viewerPlayback.paused &&
                                 Math.abs(window.viewerPlayback.position_s - t) < 1e-6, { timeout: 5000, polling: 50 }, t);
      await new Promise((r) => setTimeout(r, 250));  // the frame at t reaches the page and is drawn
      return page.evaluate(() => window.viewerStats.lastCycle);
    };
    await page.evaluate(() => window.viewerPlaybackRequest({ action: 'pause' }));
    const cycleA = await seekTo(a);
    const shotA = await page.screenshot({ encoding: 'base64', clip });
    await new Promise((r) => setTimeout(r, 300));
    const heldCycle = await page.evaluate(() => window.viewerStats.lastCycle);
    const cycleB = await seekTo(b);
    const shotB = await page.screenshot({ encoding: 'base64', clip });
    const diff = await differing(shotA, shotB);
    const result = { rect: clip, seek_s: [a, b], cycles: [cycleA, cycleB], held: heldCycle, changedPixels: diff.count, pixels: diff.total };
    console.log(JSON.stringify(result));
    if (heldCycle !== cycleA) fail(`paused, yet the page drew cycle ${heldCycle} after ${cycleA}`);
    if (!(cycleB > cycleA)) fail(`seek to ${b} s drew cycle ${cycleB}, to ${a} s cycle ${cycleA}`);
    if (diff.count < 0.002 * diff.total) fail(`the model's screen area did not change: ${diff.count} of ${diff.total} pixels`);
    if (consoleErrors.length) fail(`console errors: ${consoleErrors.join(' | ')}`);
  } else {
  // Pairs of screenshots gapMs apart until one pair differs (a live scene deforms at its own
  // pace: the trainer's duct only while a tool or the catheter loads it), at most `attempts`.
  const attempts = Number(args.attempts ?? 1);
  let changed = null, cycleFirst = 0, cycleSecond = 0;
  for (let attempt = 0; attempt < attempts; ++attempt) {
    const first = await page.screenshot({ encoding: 'base64', clip });
    cycleFirst = await page.evaluate(() => window.viewerStats.lastCycle);
    await new Promise((r) => setTimeout(r, gapMs));
    const second = await page.screenshot({ encoding: 'base64', clip });
    cycleSecond = await page.evaluate(() => window.viewerStats.lastCycle);
    changed = await differing(first, second);  // pixels that differ, decoded in the page
    if (cycleSecond !== cycleFirst && changed.count >= 0.002 * changed.total) break;
  }
  const result = { rect: clip, cycles: [cycleFirst, cycleSecond], changedPixels: changed.count, pixels: changed.total };
  if (args['expect-deformation']) {
    // The tissue model really deformed: the largest displacement drawn (not just pixels that
    // changed because an instrument moved across it).
    const peak = await page.evaluate((i) => window.viewerStats.peakDisplacementM[i] || 0, modelIndex);
    result.peakDisplacementM = peak;
    if (!(peak >= Number(args['expect-deformation']))) fail(`model ${modelIndex} deformed by at most ${peak} m`);
  }
  if (args['screenshot-cycle']) {
    await page.waitForFunction((c) => window.viewerStats.lastCycle >= c, { timeout: 20000, polling: 50 },
                               Number(args['screenshot-cycle']));
  }
  if (args.screenshot) await page.screenshot({ path: args.screenshot });
  if (args['expect-metrics']) {
    // The appliance's trainee metrics arrive in the frames (wire format 1.1) and the session
    // panel shows them: a task state and an instrument's path length.
    try {
      await page.waitForFunction(() => { const t = document.getElementById('session').textContent;
                                         return t.includes('trainee metrics') && t.includes('path mm') && t.includes('task'); },
                                 { timeout: Number(args['expect-metrics']) * 1000, polling: 100 });
      result.metricsPanel = await page.evaluate(() => document.getElementById('session').textContent);
    } catch {
      fail(`no trainee metrics in the session panel within ${args['expect-metrics']} s`);
    }
  }
  if (args['fault-command']) {
    // A stream that latches a fault (e.g. the trainer not armed) is started now.
    const child = spawn('/bin/sh', ['-c', args['fault-command']], { stdio: 'ignore' });
    child.on('error', (e) => fail(`fault command: ${e}`));
  }
  if (args['expect-fault']) {
    // The stream latches a fault: the banner must show it.
    try {
      await page.waitForFunction(() => { const b = document.getElementById('banner');
                                         return b.style.display === 'block' && b.textContent.startsWith('FAULT'); },
                                 { timeout: Number(args['expect-fault']) * 1000, polling: 100 });
    } catch {
      fail(`no fault banner within ${args['expect-fault']} s`);
    }
  }
  if (cycleSecond === cycleFirst) fail(`no new frame between the screenshots (cycle ${cycleFirst})`);
  if (changed.count < 0.002 * changed.total) fail(`the model's screen area did not change: ${changed.count} of ${changed.total} pixels`);
  if (consoleErrors.length) fail(`console errors: ${consoleErrors.join(' | ')}`);

  if (seconds > 0) {
    // Measure: reset the counters, keep the page open, then report.
    await page.evaluate(() => { window.viewerStats.hops = []; window.viewerStats.rebuildMs = [];
                                window.viewerMeasureStart = { t: performance.now(), drawn: window.viewerStats.framesDrawn,
                                                              raf: window.viewerStats.rafCount, received: window.viewerStats.framesReceived }; });
    await new Promise((r) => setTimeout(r, seconds * 1000));
    result.measure = await page.evaluate(() => {
      const s = window.viewerStats, m = window.viewerMeasureStart;
      const elapsed = (performance.now() - m.t) / 1000;
      const pct = (values, p) => { if (!values.length) return NaN; const v = [...values].sort((x, y) => x - y);
                                   return v[Math.min(v.length - 1, Math.floor(p * v.length))]; };
      const names = ['cycle_to_sent', 'sent_to_viewer', 'viewer_to_websocket', 'websocket_to_page', 'page_to_drawn', 'cycle_to_drawn'];
      const hops = {};
      names.forEach((n, k) => { const v = s.hops.map((h) => h[k]);
        hops[n] = { mean: v.reduce((a, b) => a + b, 0) / Math.max(1, v.length), p50: pct(v, 0.5), p99: pct(v, 0.99), max: pct(v, 1) }; });
      return { seconds: elapsed, frames_received_per_s: (s.framesReceived - m.received) / elapsed,
               frames_drawn_per_s: (s.framesDrawn - m.drawn) / elapsed, raf_per_s: (s.rafCount - m.raf) / elapsed,
               samples: s.hops.length, hops_ms: hops, frame_bytes: s.frameBytes,
               browser_rebuild_ms: s.rebuildMs.length ? { mean: s.rebuildMs.reduce((a, b) => a + b, 0) / s.rebuildMs.length,
                                                          p99: pct(s.rebuildMs, 0.99), samples: s.rebuildMs.length } : null };
    });
  }
  console.log(JSON.stringify(result, null, 1));
  if (args.json) fs.writeFileSync(args.json, JSON.stringify(result, null, 1));
  }  // live
} catch (error) {
  fail(error.message);
} finally {
  await browser.close();
}
