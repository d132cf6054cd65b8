// Loads a .glb with three.js's own GLTFLoader (npm `three`, pinned by package-lock.json) in
// node and prints, as JSON, what three.js would draw:
//
//   node inspect.mjs FILE.glb [--faces]
//
// * meshes / instancedMeshes: the Mesh and InstancedMesh objects in the loaded scene (three.js
//   turns every EXT_mesh_gpu_instancing node into InstancedMeshes; it ignores MSFT_lod, so
//   only the full levels are drawn);
// * instances: the instances of all InstancedMeshes together;
// * trianglesPerFrame: what one frame draws with nothing culled (every instance of every
//   instanced mesh, every plain mesh once);
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
// No DOM is needed: a .glb without images never reaches the image loaders.

import { readFileSync } from 'node:fs';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { Matrix3, Matrix4, Vector3, Box3 } from 'three';

const args = process.argv.slice(2);
const faces = args.includes('--faces');
const files = args.filter((a) => !a.startsWith('--'));
if (files.length !== 1) {
  console.error('usage: node inspect.mjs FILE.glb [--faces]');
  process.exit(2);
}

const bytes = readFileSync(files[0]);
const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const gltf = await new Promise((resolve, reject) => {
  new GLTFLoader().parse(data, '', resolve, reject);
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
gltf.scene.traverse((o) => {
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
console.log(JSON.stringify(report, null, 2));
