// u = Φ q (+ the static correction R·F and the static part of modes not streamed), the same
// sums as tools/viewer/src/reconstruct.cpp, for the browser-side placement (--reconstruct browser).
export class ModalRebuilder {
  constructor(model, buffer) {
    const part = (name, Type) => { const [w, c] = model.layout[name]; return new Type(buffer, w * 4, c); };
    this.n3 = 3 * model.node_count;
    this.r = model.mode_count;
    this.phi = part('mode_shapes', Float32Array);
    this.omega2 = part('omega_squared', Float32Array);
    this.surface = part('surface_nodes', Uint32Array);
    this.residual = part('residual_compliance', Float32Array);
    this.correct = model.static_correction && this.residual.length > 0;
    this.surfaceIndex = new Int32Array(model.node_count).fill(-1);
    this.surface.forEach((node, s) => { this.surfaceIndex[node] = s; });
    this.q = new Float32Array(this.r);
    this.out = new Float32Array(this.n3);
  }

  rebuild(coordinates, loads) {
    const { r, phi, q, out } = this;
    q.fill(0);
    q.set(coordinates.subarray(0, Math.min(coordinates.length, r)));
    const correct = this.correct && loads.length > 0;
    let used = coordinates.length;
    if (correct) {
      for (let i = coordinates.length; i < r; ++i) {
        let projected = 0;
        for (const load of loads) for (let a = 0; a < 3; ++a) projected += phi[(3 * load.node + a) * r + i] * load.force[a];
        q[i] = projected / this.omega2[i];
      }
      used = r;
    }
    for (let row = 0; row < this.n3; ++row) {
      let sum = 0;
      const base = row * r;
      for (let i = 0; i < used; ++i) sum += phi[base + i] * q[i];
      out[row] = sum;
    }
    if (!correct) return out;
    const s = this.surface.length, s3 = 3 * s;
    for (const load of loads) {
      const sl = this.surfaceIndex[load.node];
      if (sl < 0) continue;
      for (let b = 0; b < 3; ++b) {
        const f = load.force[b];
        if (f === 0) continue;
        const base = (3 * sl + b) * s3;
        for (let k = 0; k < s; ++k) {
          const u = 3 * this.surface[k];
          out[u] += this.residual[base + 3 * k] * f;
          out[u + 1] += this.residual[base + 3 * k + 1] * f;
          out[u + 2] += this.residual[base + 3 * k + 2] * f;
        }
      }
    }
    return out;
  }
}
