// The page's own rebuild (tools/viewer/web/src/reconstruct.js, used with --reconstruct browser)
// against the viewer's C++ one on the same duct, state and loads (fixture written by
// viewer_core_test). usage: node check_browser_rebuild.mjs SOURCE_DIR FIXTURE_DIR
import fs from 'node:fs';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const [sourceDir, dir] = process.argv.slice(2);
const { ModalRebuilder } = await import(pathToFileURL(path.join(sourceDir, 'tools/viewer/web/src/reconstruct.js')));
const read = (name) => { const b = fs.readFileSync(path.join(dir, name)); return b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength); };
const scene = JSON.parse(fs.readFileSync(path.join(dir, 'scene.json'), 'utf8'));
const model = scene.models[0];
if (!model.browser_rebuilds || !model.static_correction) throw new Error('fixture is not a browser-rebuilt duct with static correction');
const rebuilder = new ModalRebuilder(model, read('model0.bin'));
const out = rebuilder.rebuild(new Float32Array(read('coordinates.bin')), JSON.parse(fs.readFileSync(path.join(dir, 'loads.json'), 'utf8')));
const expected = new Float32Array(read('expected.bin'));
let largest = 0, worst = 0;
for (let i = 0; i < expected.length; ++i) {
  largest = Math.max(largest, Math.abs(expected[i]));
  worst = Math.max(worst, Math.abs(expected[i] - out[i]));
}
console.log(`browser rebuild vs viewer: ${expected.length} values, largest ${largest.toExponential(3)} m, worst difference ${worst.toExponential(3)} m`);
if (!(largest > 1e-6) || !(worst <= 1e-5 * largest)) {
  console.error('check_browser_rebuild: FAIL');
  process.exit(1);
}
