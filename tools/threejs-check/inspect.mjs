// Loads a .glb with three.js's own GLTFLoader (npm `three`, pinned by package-lock.json) in
// node and prints, as JSON, what three.js would draw:
//
//   node inspect.mjs FILE.glb [--faces] [--size 800x600]
//
// * meshes / instancedMeshes: the Mesh and InstancedMesh objects of the full levels in the
//   loaded scene (three.js turns every EXT_mesh_gpu_instancing node into InstancedMeshes; its
//   GLTFLoader ignores MSFT_lod, so without msft-lod.mjs only the full levels are drawn);
// * instances: the instances of all those InstancedMeshes together;
// * trianglesPerFrame: what one frame draws with full levels only and nothing culled (every
//   instance of every instanced mesh, every plain mesh once): three.js without msft-lod.mjs;
// * lod: with msft-lod.mjs (each MSFT_lod node a CellLOD choosing its levels from the file's
//   camera, at the aspect of --size; per instance for instanced nodes): `lods` (LOD objects),
//   `instancesPerLevel` (instances drawn at each level, finest first), `trianglesPerLevel` (of one instance, per level, from
//   the first instanced LOD), `trianglesPerFrame` (the chosen levels, nothing culled) and
//   `visibleTrianglesPerFrame` (also leaving out objects whose bounding sphere is outside the
//   camera's frustum, as three.js's renderer does);
// * per InstancedMesh: its instance count, triangles per instance, and how many of its instance
//   matrices have a negative determinant (mirror).
//
// With --faces each instanced mesh's triangles are checked as three.js rasterises them:
// WebGLRenderer picks the front-face winding from the object's matrixWorld alone
// (`frontFaceCW = matrixWorld.determinant() < 0`); an instance matrix never flips it. For each
// instance the front-face normal of every world-space triangle is compared with
//   - the direction from the instance's centre (the centre of its world-space box) to the
//     triangle: on a convex shape an outward face points away from any inside point, so a
//     triangle whose front normal points at the centre shows its back to the outside
//     (`inwardFaces`; on a closed mesh with back-face culling, the viewer sees the inside);
//   - the normal three.js shades it with (the vertex normals through `mat3(instanceMatrix)`
//     divided by the squared column lengths, as the instancing shader chunk does, then the
//     object's normal matrix): `shadingDisagrees` counts triangles lit from the other side.
// Both are reported separately for instances with positive and negative determinants.
//
// * skinned: per SkinnedMesh its bones' names, vertex count and the sums of its skinIndex and
//   skinWeight attributes (what three.js skins with); animations: each clip's name, duration,
//   track count and each track's values at 0, 1/4, 1/2, 3/4 and 1 of its duration.
//
// No DOM is needed: images (an impostor's texture) are not decoded; every texture is an empty
// THREE.Texture (a plugin answers GLTFLoader's loadTexture first).

import { readFileSync } from 'node:fs';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { Frustum, Matrix3, Matrix4, PerspectiveCamera, Sphere, Texture, Vector3, Box3 } from 'three';
import { GLTFMsftLodPlugin } from './msft-lod.mjs';

const args = process.argv.slice(2);
const faces = args.includes('--faces');
const sizeAt = args.indexOf('--size');
const [width, height] = (sizeAt >= 0 ? args[sizeAt + 1] : '800x600').split('x').map(Number);
const files = args.filter((a, i) => !a.startsWith('--') && !(sizeAt >= 0 && i === sizeAt + 1));
if (files.length !== 1) {
  console.error('usage: node inspect.mjs FILE.glb [--faces] [--size 800x600]');
  process.exit(2);
}

const bytes = readFileSync(files[0]);
const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const loader = new GLTFLoader();
loader.register(() => ({ name: 'no-images', loadTexture: () => Promise.resolve(new Texture()) }));
loader.register((parser) => new GLTFMsftLodPlugin(parser));
const gltf = await new Promise((resolve, reject) => {
  loader.parse(data, '', resolve, reject);
});
gltf.scene.updateMatrixWorld(true);

function triangleCount(geometry) {
  return geometry.index ? geometry.index.count / 3 : geometry.attributes.position.count / 3;
}

function vertexIndex(geometry, k) {
  return geometry.index ? geometry.index.getX(k) : k;
}

// Front-face and shading checks of one instance (see the header).
function checkInstance(mesh, instanceMatrix, tally) {
  const geometry = mesh.geometry;
  const world = new Matrix4().multiplyMatrices(mesh.matrixWorld, instanceMatrix);
  const frontSign = mesh.matrixWorld.determinant() < 0 ? -1 : 1;
  const position = geometry.attributes.position;
  const normal = geometry.attributes.normal;
  const n = position.count;
  const worldPos = new Float64Array(n * 3);
  const box = new Box3();
  const v = new Vector3();
  for (let i = 0; i < n; i++) {
    v.fromBufferAttribute(position, i).applyMatrix4(world);
    worldPos[3 * i] = v.x;
    worldPos[3 * i + 1] = v.y;
    worldPos[3 * i + 2] = v.z;
    box.expandByPoint(v);
  }
  const centre = box.getCenter(new Vector3());
  // The instancing shader: transformedNormal /= (|im col 0|², |im col 1|², |im col 2|²);
  // transformedNormal = im * transformedNormal; then the object's normal matrix.
  const im = new Matrix3().setFromMatrix4(instanceMatrix);
  const e = im.elements;
  const colSq = [0, 1, 2].map((c) => e[3 * c] ** 2 + e[3 * c + 1] ** 2 + e[3 * c + 2] ** 2);
  const objectNormal = new Matrix3().getNormalMatrix(mesh.matrixWorld);
  const shade = (i) => {
    const s = new Vector3().fromBufferAttribute(normal, i);
    s.set(s.x / colSq[0], s.y / colSq[1], s.z / colSq[2]).applyMatrix3(im).applyMatrix3(objectNormal);
    return s;
  };
  const p = (i) => new Vector3(worldPos[3 * i], worldPos[3 * i + 1], worldPos[3 * i + 2]);
  const tris = triangleCount(geometry);
  for (let t = 0; t < tris; t++) {
    const ia = vertexIndex(geometry, 3 * t);
    const ib = vertexIndex(geometry, 3 * t + 1);
    const ic = vertexIndex(geometry, 3 * t + 2);
    const a = p(ia);
    const b = p(ib);
    const c = p(ic);
    const front = new Vector3()
      .subVectors(b, a)
      .cross(new Vector3().subVectors(c, a))
      .multiplyScalar(frontSign);
    const mid = a.clone().add(b).add(c).divideScalar(3);
    tally.triangles += 1;
    if (front.dot(mid.sub(centre)) <= 0) {
      tally.inwardFaces += 1;
    }
    if (normal) {
      const s = shade(ia).add(shade(ib)).add(shade(ic));
      if (front.dot(s) <= 0) {
        tally.shadingDisagrees += 1;
      }
    }
  }
}

const report = {
  file: files[0],
  meshes: 0,
  instancedMeshes: 0,
  instances: 0,
  trianglesPerFrame: 0,
  instanced: [],
};
const m = new Matrix4();
// The full levels: what three.js draws without msft-lod.mjs (a CellLOD's other levels are
// skipped).
const coarser = new Set();
for (const lod of gltf.lods) {
  lod.levels.slice(1).forEach((l) => l.object.traverse((o) => coarser.add(o)));
}
gltf.scene.traverse((o) => {
  if (coarser.has(o)) {
    return;
  }
  if (o.isInstancedMesh) {
    const tris = triangleCount(o.geometry);
    const entry = {
      name: o.name,
      count: o.count,
      trianglesPerInstance: tris,
      negativeDeterminant: 0,
    };
    const tallies = {
      positive: { instances: 0, triangles: 0, inwardFaces: 0, shadingDisagrees: 0 },
      negative: { instances: 0, triangles: 0, inwardFaces: 0, shadingDisagrees: 0 },
    };
    for (let i = 0; i < o.count; i++) {
      o.getMatrixAt(i, m);
      const negative = m.determinant() < 0;
      if (negative) {
        entry.negativeDeterminant += 1;
      }
      if (faces) {
        const tally = negative ? tallies.negative : tallies.positive;
        tally.instances += 1;
        checkInstance(o, m, tally);
      }
    }
    if (faces) {
      entry.faces = tallies;
    }
    report.instancedMeshes += 1;
    report.instances += o.count;
    report.trianglesPerFrame += tris * o.count;
    report.instanced.push(entry);
  } else if (o.isMesh) {
    report.meshes += 1;
    report.trianglesPerFrame += triangleCount(o.geometry);
  }
});
// Levels chosen from the file's camera (or, without one, a camera that frames the scene).
let camera = gltf.cameras[0];
if (!camera) {
  camera = new PerspectiveCamera(45, width / height, 0.1, 1e4);
  const box = new Box3().setFromObject(gltf.scene);
  const c = box.getCenter(new Vector3());
  camera.position.copy(c).add(new Vector3(0, 0.5, 1).multiplyScalar(box.getSize(new Vector3()).length()));
  camera.lookAt(c);
}
camera.aspect = width / height;
camera.updateProjectionMatrix();
camera.updateMatrixWorld(true);
const frustum = new Frustum().setFromProjectionMatrix(
  new Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse),
);
const lod = {
  camera: gltf.cameras[0] ? 'file' : 'framing',
  lods: gltf.lods.length,
  instancesPerLevel: [],
  trianglesPerLevel: [],
  trianglesPerFrame: 0,
  visibleTrianglesPerFrame: 0,
};
const sphere = new Sphere();
const drawn = (o, perLevel, level) => {
  if (!o.isMesh) {
    return;
  }
  const n = o.isInstancedMesh ? o.count : 1;
  const tris = triangleCount(o.geometry) * n;
  lod.trianglesPerFrame += tris;
  if (level !== undefined) {
    perLevel[level] = (perLevel[level] ?? 0) + n;
  }
  if (!o.frustumCulled) {
    lod.visibleTrianglesPerFrame += tris;
    return;
  }
  if (o.isInstancedMesh) {
    if (o.boundingSphere === null) o.computeBoundingSphere();
    sphere.copy(o.boundingSphere);
  } else {
    if (o.geometry.boundingSphere === null) o.geometry.computeBoundingSphere();
    sphere.copy(o.geometry.boundingSphere);
  }
  if (frustum.intersectsSphere(sphere.applyMatrix4(o.matrixWorld))) {
    lod.visibleTrianglesPerFrame += tris;
  }
};
const inLod = new Set();
for (const l of gltf.lods) {
  l.update(camera);
  l.traverse((o) => inLod.add(o));
  l.levels.forEach((v, level) => {
    if (v.object.visible) {
      v.object.traverse((o) => drawn(o, lod.instancesPerLevel, level));
    }
  });
  if (lod.trianglesPerLevel.length === 0 && l.levels[0].object.isInstancedMesh) {
    lod.trianglesPerLevel = l.levels.map((v) => (v.object.isMesh ? triangleCount(v.object.geometry) : 0));
  }
}
gltf.scene.traverse((o) => {
  if (!inLod.has(o)) {
    drawn(o, [], undefined);
  }
});
lod.instancesPerLevel = Array.from(lod.instancesPerLevel, (v) => v ?? 0);
report.lod = lod;
report.skinned = [];
gltf.scene.traverse((o) => {
  if (!o.isSkinnedMesh) {
    return;
  }
  const index = o.geometry.attributes.skinIndex;
  const weight = o.geometry.attributes.skinWeight;
  let jointIndexSum = 0;
  let weightSum = 0;
  for (let i = 0; i < index.count; i++) {
    for (let k = 0; k < 4; k++) {
      jointIndexSum += index.getComponent(i, k);
      weightSum += weight.getComponent(i, k);
    }
  }
  report.skinned.push({
    name: o.name,
    bones: o.skeleton.bones.map((b) => b.name),
    vertices: index.count,
    jointIndexSum,
    weightSum,
  });
});
report.animations = gltf.animations.map((a) => ({
  name: a.name,
  duration: a.duration,
  tracks: a.tracks.length,
  // Each track's value at 0, 1/4, 1/2, 3/4 and all of the clip's duration, as three.js
  // interpolates it (the track names are "node.property").
  sampled: a.tracks.map((t) => {
    const at = (time) => Array.from(t.createInterpolant().evaluate(time));
    return { name: t.name, values: [0, 0.25, 0.5, 0.75, 1].map((f) => at(f * a.duration)) };
  }),
}));
console.log(JSON.stringify(report, null, 2));
