// A GLTFLoader plugin for MSFT_lod, which three.js's GLTFLoader ignores (it draws the full
// level only). Used by inspect.mjs (node) and browser/index.html:
//
//   loader.register((parser) => new GLTFMsftLodPlugin(parser));
//
// After the scene is built, each scene node with an MSFT_lod extension is replaced by a
// `CellLOD` (a THREE.LOD) holding the node itself as level 0 and its level nodes (which are
// outside the scene) as levels 1, 2, ...; a level node's mesh that several nodes share is one
// geometry in three.js too (GLTFLoader clones the Mesh, not its BufferGeometry).
//
// Level choice. The node's extras give MSFT_screencoverage c_0 > c_1 > ... > c_n = 0: level k
// is drawn while the object covers at least c_k of the screen. Coverage is read as the fraction
// of the viewport's height that the bounding sphere's diameter spans (Thicket writes halving
// coverages for levels of halving resolution, so a cell of the mesher keeps about the same
// size on screen): for a perspective camera with vertical field of view fov at distance d,
//
//   coverage(d) = 2r / (2 d tan(fov/2)) = r / (d tan(fov/2)),
//
// so level k is drawn from the distance D_k = r / (c_{k-1} tan(fov/2)) on (level 0 from 0);
// with an orthographic camera coverage = 2r zoom / (top − bottom). The distances are worked
// out every frame from the camera's own fov, so a zoom or a resize needs nothing else.
//
// Instanced nodes (a cell of a forest: EXT_mesh_gpu_instancing, the same placements on every
// level) choose per instance: r is one instance's bounding-sphere radius (the level-0 geometry's
// times the instance's scale) and d the distance from the camera to its centre; each level's
// InstancedMesh draws the instances that chose it (their matrices copied in when the camera
// has moved). A cell whose nearest point (of the box around all its instances) is already
// past the last switch draws its coarsest level with every instance and does no per-instance
// work. Each level's bounding sphere is the whole cell's, so three.js culls cells, never an
// instance it should draw. A plain node chooses with its own bounding sphere, at the distance
// to its box.

import { Box3, LOD, Matrix4, Sphere, Vector3 } from 'three';

const EXTENSION = 'MSFT_lod';

const _camera = new Vector3();
const _matrix = new Matrix4();
const _scale = new Vector3();

/// Bounding sphere radius of one instance and the world box of all instances (or of the
/// object itself when it is not instanced).
function extentOf(object) {
  object.updateWorldMatrix(true, true);
  const mesh = object.isMesh ? object : object.children.find((c) => c.isMesh);
  if (!mesh) {
    const box = new Box3().setFromObject(object);
    return { radius: box.getBoundingSphere(new Sphere()).radius, box };
  }
  const geometry = mesh.geometry;
  if (!geometry.boundingSphere) geometry.computeBoundingSphere();
  if (!geometry.boundingBox) geometry.computeBoundingBox();
  if (!mesh.isInstancedMesh) {
    const box = new Box3().setFromObject(object);
    _scale.setFromMatrixScale(mesh.matrixWorld);
    return { radius: geometry.boundingSphere.radius * Math.max(_scale.x, _scale.y, _scale.z), box };
  }
  const box = new Box3();
  const one = new Box3();
  let scale = 0;
  for (let i = 0; i < mesh.count; i++) {
    mesh.getMatrixAt(i, _matrix);
    _matrix.premultiply(mesh.matrixWorld);
    _scale.setFromMatrixScale(_matrix);
    scale = Math.max(scale, _scale.x, _scale.y, _scale.z);
    box.union(one.copy(geometry.boundingBox).applyMatrix4(_matrix));
  }
  return { radius: geometry.boundingSphere.radius * scale, box };
}

/// A THREE.LOD whose level follows MSFT_screencoverage (see the header).
export class CellLOD extends LOD {
  constructor(coverage, radius, box) {
    super();
    this.type = 'CellLOD';
    this.coverage = coverage;
    this.radius = radius;
    this.box = box;
    this.instanced = null;
    this.lastCamera = new Matrix4().set(NaN, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    this.lastFov = NaN;
  }

  /// Per-instance choice when every level is one InstancedMesh with the same instances.
  prepareInstances() {
    const meshes = this.levels.map((l) => l.object);
    const first = meshes[0];
    if (!meshes.every((m) => m.isInstancedMesh && m.count === first.count)) {
      return;
    }
    first.updateWorldMatrix(true, false);
    const geometry = first.geometry;
    if (!geometry.boundingSphere) geometry.computeBoundingSphere();
    const n = first.count;
    const matrices = new Float32Array(first.instanceMatrix.array.slice(0, 16 * n));
    const centres = new Float32Array(3 * n);
    const radii = new Float32Array(n);
    const m = new Matrix4();
    const c = new Vector3();
    for (let i = 0; i < n; i++) {
      m.fromArray(matrices, 16 * i).premultiply(first.matrixWorld);
      c.copy(geometry.boundingSphere.center).applyMatrix4(m);
      c.toArray(centres, 3 * i);
      _scale.setFromMatrixScale(m);
      radii[i] = geometry.boundingSphere.radius * Math.max(_scale.x, _scale.y, _scale.z);
    }
    first.computeBoundingSphere();
    for (const mesh of meshes) {
      mesh.boundingSphere = first.boundingSphere.clone();
    }
    this.instanced = { meshes, matrices, centres, radii, count: n };
  }

  /// The fraction of the viewport's height a sphere of `radius` at `distance` covers.
  static coverageAt(camera, radius, distance) {
    if (camera.isOrthographicCamera) {
      return (2 * radius * camera.zoom) / (camera.top - camera.bottom);
    }
    const t = Math.tan((camera.fov * Math.PI) / 360) / camera.zoom;
    return distance > 0 ? radius / (distance * t) : Infinity;
  }

  /// The first level whose coverage threshold `c` meets.
  levelOf(c) {
    const last = this.levels.length - 1;
    for (let k = 0; k < last; k++) {
      if (c >= (this.coverage[k] ?? 0)) return k;
    }
    return last;
  }

  /// The level of the whole object (a plain node), or of its nearest instance.
  levelFor(camera) {
    _camera.setFromMatrixPosition(camera.matrixWorld);
    return this.levelOf(CellLOD.coverageAt(camera, this.radius, this.box.distanceToPoint(_camera)));
  }

  update(camera) {
    if (this.levels.length === 0) return;
    const nearest = this.levelFor(camera);
    const last = this.levels.length - 1;
    if (!this.instanced || nearest === last) {
      this.levels.forEach((l, k) => {
        l.object.visible = k === nearest;
      });
      if (this.instanced) {
        this.setCounts(null);
      }
      this._currentLevel = nearest;
      return;
    }
    if (camera.matrixWorld.equals(this.lastCamera) && camera.fov === this.lastFov) {
      return;
    }
    this.lastCamera.copy(camera.matrixWorld);
    this.lastFov = camera.fov;
    const { meshes, matrices, centres, radii, count } = this.instanced;
    const per = meshes.map(() => 0);
    _camera.setFromMatrixPosition(camera.matrixWorld);
    for (let i = 0; i < count; i++) {
      const dx = centres[3 * i] - _camera.x;
      const dy = centres[3 * i + 1] - _camera.y;
      const dz = centres[3 * i + 2] - _camera.z;
      const k = this.levelOf(CellLOD.coverageAt(camera, radii[i], Math.sqrt(dx * dx + dy * dy + dz * dz)));
      meshes[k].instanceMatrix.array.set(matrices.subarray(16 * i, 16 * i + 16), 16 * per[k]);
      per[k] += 1;
    }
    this.setCounts(per);
    this._currentLevel = nearest;
  }

  /// Draws `per[k]` instances with level k (already copied in), or, with `null`, every
  /// instance with the coarsest level.
  setCounts(per) {
    const { meshes, matrices, count } = this.instanced;
    const last = meshes.length - 1;
    if (per === null) {
      if (meshes[last].count === count && meshes[last].visible && this.allCoarsest) return;
      meshes[last].instanceMatrix.array.set(matrices);
      per = meshes.map((_, k) => (k === last ? count : 0));
      this.allCoarsest = true;
      this.lastCamera.elements[0] = NaN;
    } else {
      this.allCoarsest = false;
    }
    meshes.forEach((mesh, k) => {
      mesh.count = per[k];
      mesh.visible = per[k] > 0;
      mesh.instanceMatrix.needsUpdate = true;
    });
  }
}

export class GLTFMsftLodPlugin {
  constructor(parser) {
    this.parser = parser;
    this.name = EXTENSION;
  }

  async afterRoot(result) {
    const parser = this.parser;
    const nodes = parser.json.nodes || [];
    const found = [];
    for (const scene of result.scenes) {
      scene.traverse((object) => {
        const a = parser.associations.get(object);
        if (a && a.nodes !== undefined && nodes[a.nodes]?.extensions?.[EXTENSION]) {
          found.push([object, nodes[a.nodes]]);
        }
      });
    }
    result.lods = [];
    for (const [object, def] of found) {
      const ids = def.extensions[EXTENSION].ids || [];
      const levels = await Promise.all(ids.map((id) => parser.getDependency('node', id)));
      const coverage = def.extras?.MSFT_screencoverage ?? ids.map((_, k) => 0.5 ** (k + 1)).concat([0]);
      const parent = object.parent;
      const { radius, box } = extentOf(object);
      const lod = new CellLOD(coverage, radius, box);
      lod.name = object.name;
      parent.add(lod);
      parent.remove(object);
      // Level 0 and the level nodes carry the same node transform: the LOD adds none.
      lod.addLevel(object, 0);
      levels.forEach((level, k) => lod.addLevel(level, k + 1));
      lod.prepareInstances();
      result.lods.push(lod);
    }
  }
}
