// Decodes one "TVF1" binary frame (tools/viewer/src/view_frame.hpp) into typed-array views.
const MAGIC = 0x31465654;
const INSTRUMENT_FLOATS = 16;  // shaft start, hinge, jaw 0 tip, jaw 1 tip, force, flags
const CONTACT_FLOATS = 7;      // point, force on the tissue, instrument

export function decodeFrame(buffer, sceneInfo) {
  const view = new DataView(buffer);
  if (view.getUint32(0, true) !== MAGIC) throw new Error('not a TVF1 frame');
  const headerBytes = view.getUint32(4, true);
  const big = (at) => Number(view.getBigInt64(at, true));
  const frame = {
    sequence: Number(view.getBigUint64(8, true)),
    cycle: Number(view.getBigUint64(16, true)),
    times: { cycleNs: big(24), sentNs: big(32), receivedNs: big(40), handedNs: big(48) },
    viewerRebuildUs: view.getFloat64(56, true),
    faults: view.getUint32(64, true),
    flags: view.getUint32(68, true),
    models: [],
    instruments: [],
    contacts: [],
  };
  const modelCount = view.getUint32(72, true);
  const instrumentCount = view.getUint32(76, true);
  if (sceneInfo && (modelCount !== sceneInfo.models.length || instrumentCount !== sceneInfo.instruments.length)) {
    throw new Error('frame does not match the scene');
  }
  let at = headerBytes;
  for (let i = 0; i < modelCount; ++i) {
    const floatCount = view.getUint32(at, true);
    const loadCount = view.getUint32(at + 4, true);
    at += 8;
    const floats = new Float32Array(buffer, at, floatCount);
    at += 4 * floatCount;
    const loads = [];
    for (let l = 0; l < loadCount; ++l) {
      loads.push({ node: view.getUint32(at, true),
                   force: [view.getFloat32(at + 4, true), view.getFloat32(at + 8, true), view.getFloat32(at + 12, true)] });
      at += 16;
    }
    frame.models.push({ floats, loads });
  }
  for (let i = 0; i < instrumentCount; ++i) {
    frame.instruments.push(new Float32Array(buffer, at, INSTRUMENT_FLOATS));
    at += 4 * INSTRUMENT_FLOATS;
  }
  const contactCount = view.getUint32(at, true);
  at += 4;
  for (let c = 0; c < contactCount; ++c) {
    frame.contacts.push(new Float32Array(buffer, at, CONTACT_FLOATS));
    at += 4 * CONTACT_FLOATS;
  }
  return frame;
}
