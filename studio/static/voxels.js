// The painter's coarse grid: one instanced cube per occupied voxel, coloured per voxel, picked by ray.
// Cells are drawn in grid units: voxel (x, y, z) is the unit cube [x, x+1) × [y, y+1) × [z, z+1), +Y up.
import { THREE } from '/static/viewer3d.js';

const GAP = 0.92;  // cube edge: a small gap shows the voxels apart

export class VoxelGrid {
  constructor(viewer) {
    this.viewer = viewer;
    this.raycaster = new THREE.Raycaster();
    this.color = new THREE.Color();
  }

  // data: /api/asset's shape and cells (flat x, y, z triples).
  set(data) {
    const [X, Y, Z] = data.shape;
    this.shape = data.shape;
    this.cells = data.cells;
    this.count = data.cells.length / 3;
    this.index = new Int32Array(X * Y * Z).fill(-1);
    const geometry = new THREE.BoxGeometry(GAP, GAP, GAP);
    const material = new THREE.MeshStandardMaterial({ roughness: 0.9, metalness: 0.0 });
    this.mesh = new THREE.InstancedMesh(geometry, material, this.count);
    const m = new THREE.Matrix4();
    for (let i = 0; i < this.count; i++) {
      const [x, y, z] = [this.cells[3 * i], this.cells[3 * i + 1], this.cells[3 * i + 2]];
      m.makeTranslation(x + 0.5, y + 0.5, z + 0.5);
      this.mesh.setMatrixAt(i, m);
      this.mesh.setColorAt(i, this.color.set(0xffffff));
      this.index[x + X * (y + Y * z)] = i;
    }
    this.hover = new THREE.LineSegments(new THREE.EdgesGeometry(new THREE.BoxGeometry(1.02, 1.02, 1.02)),
      new THREE.LineBasicMaterial({ color: 0xffffff }));
    this.hover.visible = false;
    this.region = new THREE.Box3Helper(new THREE.Box3(), 0xffd166);
    this.region.visible = false;
    const group = new THREE.Group();
    group.add(this.mesh, this.hover, this.region);
    this.viewer.show(group);
  }

  cell(i) { return [this.cells[3 * i], this.cells[3 * i + 1], this.cells[3 * i + 2]]; }

  at(x, y, z) {
    const [X, Y, Z] = this.shape;
    if (x < 0 || y < 0 || z < 0 || x >= X || y >= Y || z >= Z) return -1;
    return this.index[x + X * (y + Y * z)];
  }

  // rgbOf(i) → [r, g, b] 0-255 (sRGB, as pipeline/palette.py gives them).
  paint(rgbOf) {
    for (let i = 0; i < this.count; i++) {
      const [r, g, b] = rgbOf(i);
      this.mesh.setColorAt(i, this.color.setRGB(r / 255, g / 255, b / 255, THREE.SRGBColorSpace));
    }
    this.mesh.instanceColor.needsUpdate = true;
    this.viewer.render();
  }

  // The voxel under a pointer event, or -1.
  pick(event) {
    const rect = this.viewer.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
      -((event.clientY - rect.top) / rect.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.viewer.camera);
    const hit = this.raycaster.intersectObject(this.mesh, false)[0];
    return hit ? hit.instanceId : -1;
  }

  showHover(i, size = 1) {
    this.hover.visible = i >= 0;
    if (i >= 0) {
      const [x, y, z] = this.cell(i);
      this.hover.position.set(x + 0.5, y + 0.5, z + 0.5);
      this.hover.scale.setScalar(size);
    }
    this.viewer.render();
  }

  showRegion(lo, hi) {
    this.region.visible = !!lo;
    if (lo) this.region.box.set(new THREE.Vector3(...lo), new THREE.Vector3(...hi.map((v) => v + 1)));
    this.viewer.render();
  }
}
