// quatcurve-three: plays a quatcurve bake in three.js as an instanced crowd, each instance
// with its own clip, time offset and speed, skinned on the GPU from the bake's skin-trs bone
// textures by the shader library `quatcurve shaders --library` generates (bones.glsl, beside
// this file), inside the user's own material. Everything the shader needs comes from the
// bake's sidecar: the files, each texture's layout uniform by name, the clips.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { decodePng16 } from './png16.js';

const LIBRARY_URL = new URL('./bones.glsl', import.meta.url);

// Declarations and the one call the library needs inside three.js's vertex shader: the
// per-instance inputs, the crowd's clock, and the time each instance is at in its clip.
const GLUE = /* glsl */ `
in vec4 skinIndex;
in vec4 skinWeight;
// Per instance: its clip (an index into the layout's clips), time offset (s) and speed.
in vec3 quatcurveInstance;
uniform float quatcurveTime;
mat4 quatcurveSkinMatrix() {
  uint clip = uint(quatcurveInstance.x + 0.5);
  float time = quatcurveTime * quatcurveInstance.z + quatcurveInstance.y;
#ifdef QUATCURVE_WRAP_OPEN
  BoneClip c = bone_layout.clips[clip];
  float span = float(max(c.frames, 1u) - 1u) / c.rate;
  if (c.looping == 0u && span > 0.0) time -= floor(time / span) * span;
#endif
  return bone_skin_matrix(clip, uvec4(skinIndex + 0.5), skinWeight, time);
}
`;

/**
 * A bake loaded: its sidecar, the baked glTF's skinned meshes and the bone textures.
 * @typedef {object} Bake
 * @property {object} sidecar the sidecar JSON as the bake wrote it
 * @property {string[]} clips clip names, in the sidecar's order
 * @property {{geometry: THREE.BufferGeometry, material: THREE.Material, skin: number, name: string}[]} meshes
 * @property {Map<string, THREE.DataTexture>} textures bone textures by file name, rows top-down
 * @property {(options?: CrowdOptions) => Crowd} createCrowd
 */

/**
 * Loads the bake whose sidecar is at `sidecarUrl` (a `--texture skin-trs` bake of
 * `--format exr` or `png16`): the sidecar, the baked glTF (three.js's GLTFLoader) and every
 * bone texture (EXRLoader, rows put back top-down; PNG16 decoded to 16 bits).
 * @param {string | URL} sidecarUrl
 * @param {{manager?: THREE.LoadingManager}} [options]
 * @returns {Promise<Bake>}
 */
export async function loadBake(sidecarUrl, { manager } = {}) {
  const url = new URL(sidecarUrl, globalThis.location?.href);
  const sidecar = await fetchOk(url).then((r) => r.json());
  const name = url.pathname.split('/').pop();
  if (sidecar.texture !== 'skin-trs' || !['exr', 'png16'].includes(sidecar.format)) {
    throw new Error(
      `${name}: a ${sidecar.texture} bake of ${sidecar.format} files; quatcurve-three plays ` +
        '`quatcurve bake --texture skin-trs --format exr` (or png16) bakes',
    );
  }
  if (!sidecar.baked_file) throw new Error(`${name}: names no baked glTF (baked_file)`);
  const [library, gltf] = await Promise.all([
    fetchOk(LIBRARY_URL).then((r) => r.text()),
    new GLTFLoader(manager).loadAsync(new URL(sidecar.baked_file, url).href),
  ]);
  const meshes = skinnedMeshes(gltf, name);
  const textures = new Map();
  const loading = sidecar.textures.map(async (record) => {
    textures.set(record.file, await boneTexture(new URL(record.file, url), record, sidecar, manager));
  });
  await Promise.all(loading);
  const bake = { sidecar, clips: sidecar.clips.map((c) => c.name), meshes, textures, library };
  bake.createCrowd = (options) => new Crowd(bake, options);
  return bake;
}

async function fetchOk(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: ${response.status} ${response.statusText}`);
  return response;
}

/** Every skinned primitive of the glTF, in bind space, with its skin's index in the file. */
function skinnedMeshes(gltf, name) {
  const { parser } = gltf;
  const found = [];
  gltf.scene.updateMatrixWorld(true);
  gltf.scene.traverse((object) => {
    if (!object.isSkinnedMesh) return;
    // The glTF node of the mesh (a multi-primitive mesh is a group of meshes under it).
    let node = object;
    while (node && parser.associations.get(node)?.nodes === undefined) node = node.parent;
    const skin = node ? parser.json.nodes[parser.associations.get(node).nodes].skin : undefined;
    if (skin === undefined) throw new Error(`${name}: skinned mesh ${object.name} has no glTF skin`);
    const geometry = object.geometry;
    if (!geometry.attributes.skinIndex || !geometry.attributes.skinWeight) {
      throw new Error(`${name}: mesh ${object.name} has no JOINTS_0 and WEIGHTS_0`);
    }
    // Lit materials need normals; a mesh without them gets its bind pose's.
    if (!geometry.attributes.normal) geometry.computeVertexNormals();
    found.push({ geometry, material: object.material, skin, name: object.name });
  });
  if (!found.length) throw new Error(`${name}: the baked glTF has no skinned mesh`);
  return found;
}

/** A bone texture as the library samples it: RGBA floats, texel by texel, rows top-down. */
async function boneTexture(url, record, sidecar, manager) {
  const file = record.file;
  let image;
  if (sidecar.format === 'exr') {
    const loader = new EXRLoader(manager);
    loader.setDataType(sidecar.precision === 'f16' ? THREE.HalfFloatType : THREE.FloatType);
    const exr = await loader.loadAsync(url.href);
    // EXRLoader hands rows bottom-up (OpenGL's image origin); the bake's address counts them
    // from the top, as the file stores them.
    image = { ...exr.image, type: exr.type, data: flipRows(exr.image.data, exr.image.width, exr.image.height) };
  } else {
    const png = await decodePng16(await fetchOk(url).then((r) => r.arrayBuffer()), file);
    image = { ...png, type: THREE.FloatType };
  }
  if (image.width !== record.width || image.height !== record.height) {
    throw new Error(`${file}: ${image.width}x${image.height}; the sidecar says ${record.width}x${record.height}`);
  }
  const texture = new THREE.DataTexture(image.data, image.width, image.height, THREE.RGBAFormat, image.type);
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.generateMipmaps = false;
  texture.flipY = false;
  texture.colorSpace = THREE.NoColorSpace;
  texture.name = file;
  texture.needsUpdate = true;
  return texture;
}

/** Rows of an RGBA image in reverse order (a new array of the same type). */
export function flipRows(data, width, height) {
  const row = width * 4;
  const out = new data.constructor(data.length);
  for (let y = 0; y < height; y++) out.set(data.subarray(y * row, (y + 1) * row), (height - 1 - y) * row);
  return out;
}

/**
 * @typedef {object} CrowdOptions
 * @property {number} [count] instances (default 1)
 * @property {THREE.Material | ((source: THREE.Material) => THREE.Material)} [material] the
 *   material every mesh is drawn with, or a function of each mesh's glTF material; default:
 *   the glTF's own (lit, with its base colour texture)
 * @property {boolean} [wrapOpen] open (non-loop) clips wrap at their end rather than hold
 *   their last frame (loops always wrap at their period)
 */

/**
 * An instanced crowd of one bake: a THREE.Group of one InstancedMesh per skinned primitive
 * and texture. Give each instance a clip, time offset, speed and transform with
 * `setInstance`; call `update(seconds)` once a frame.
 */
export class Crowd extends THREE.Group {
  /**
   * @param {Bake} bake
   * @param {CrowdOptions} [options]
   */
  constructor(bake, { count = 1, material, wrapOpen = false } = {}) {
    super();
    this.bake = bake;
    this.count = count;
    this.wrapOpen = wrapOpen;
    /** The crowd's clock, shared by every material (seconds). */
    this.time = { value: 0 };
    this.instances = Array.from({ length: count }, () => ({ clip: 0, offset: 0, speed: 1, matrix: new THREE.Matrix4() }));
    // Each part skins its own copy: its texture and layout are its own uniforms.
    const base = typeof material === 'function' ? material : material ? () => material : (m) => m;
    this.materialFor = (source) => base(source).clone();
    // One InstancedMesh per (mesh, texture file), made when an instance first needs it.
    this.parts = new Map();
    this.dirty = true;
  }

  /**
   * Instance `i`'s clip (index or name), time offset in seconds, speed (1: the clip's own),
   * and transform in the crowd.
   * @param {number} i
   * @param {{clip?: number | string, offset?: number, speed?: number, matrix?: THREE.Matrix4, position?: THREE.Vector3}} values
   */
  setInstance(i, { clip, offset, speed, matrix, position } = {}) {
    const instance = this.instances[i];
    if (!instance) throw new RangeError(`no instance ${i}: the crowd has ${this.count}`);
    if (clip !== undefined) instance.clip = this.clipIndex(clip);
    if (offset !== undefined) instance.offset = offset;
    if (speed !== undefined) instance.speed = speed;
    if (matrix) instance.matrix.copy(matrix);
    if (position) instance.matrix.setPosition(position);
    this.dirty = true;
  }

  /** The sidecar index of clip `clip` (an index or a name). */
  clipIndex(clip) {
    const index = typeof clip === 'number' ? clip : this.bake.clips.indexOf(clip);
    if (!(index >= 0 && index < this.bake.clips.length)) {
      throw new RangeError(`no clip ${clip}: the bake has ${this.bake.clips.join(', ')}`);
    }
    return index;
  }

  /** Sets the crowd's clock to `seconds`; after instances changed, refills the instance buffers. */
  update(seconds) {
    this.time.value = seconds;
    if (this.dirty) this.fill();
  }

  /** Each instance into the InstancedMesh of its clip's texture, for every skinned mesh. */
  fill() {
    const { sidecar, meshes } = this.bake;
    const slots = new Map();
    for (const part of this.parts.values()) part.mesh.count = 0;
    for (const [m, mesh] of meshes.entries()) {
      for (const instance of this.instances) {
        const clip = sidecar.clips[instance.clip];
        const file = clip.files[mesh.skin];
        const record = sidecar.textures.find((t) => t.file === file);
        const at = record?.layout?.clips.indexOf(instance.clip) ?? -1;
        if (at < 0) throw new Error(`${file}: its layout holds no clip ${clip.name}`);
        const part = this.part(m, mesh, record);
        const slot = slots.get(part) ?? 0;
        slots.set(part, slot + 1);
        part.mesh.setMatrixAt(slot, instance.matrix);
        part.attribute.setXYZ(slot, at, instance.offset, instance.speed);
      }
    }
    for (const part of this.parts.values()) {
      part.mesh.count = slots.get(part) ?? 0;
      part.mesh.instanceMatrix.needsUpdate = true;
      part.attribute.needsUpdate = true;
    }
    this.dirty = false;
  }

  part(m, mesh, record) {
    const key = `${m} ${record.file}`;
    if (!this.parts.has(key)) {
      const geometry = mesh.geometry.clone();
      const attribute = new THREE.InstancedBufferAttribute(new Float32Array(this.count * 3), 3);
      geometry.setAttribute('quatcurveInstance', attribute);
      const material = this.skinned(this.materialFor(mesh.material), record);
      const instanced = new THREE.InstancedMesh(geometry, material, this.count);
      // The bind pose's bounds say nothing of where an animated instance is.
      instanced.frustumCulled = false;
      instanced.name = `${mesh.name} ${record.file}`;
      this.add(instanced);
      this.parts.set(key, { mesh: instanced, attribute });
    }
    return this.parts.get(key);
  }

  /** `material` skinned by the library from the texture of `record`. */
  skinned(material, record) {
    const texture = this.bake.textures.get(record.file);
    const uniforms = {
      bone_texture: { value: texture },
      bone_layout: { value: layoutValue(record.layout.fields) },
      quatcurveTime: this.time,
    };
    const library = this.bake.library;
    const previous = material.onBeforeCompile;
    material.onBeforeCompile = (shader, renderer) => {
      previous?.call(material, shader, renderer);
      Object.assign(shader.uniforms, uniforms);
      shader.vertexShader = shader.vertexShader
        .replace('#include <common>', `#include <common>\n${library}\n${GLUE}`)
        .replace('void main() {', 'void main() {\n\tmat4 quatcurveSkin = quatcurveSkinMatrix();')
        .replace(
          '#include <beginnormal_vertex>',
          '#include <beginnormal_vertex>\n\tobjectNormal = (quatcurveSkin * vec4(objectNormal, 0.0)).xyz;',
        )
        .replace(
          '#include <begin_vertex>',
          '#include <begin_vertex>\n\ttransformed = (quatcurveSkin * vec4(transformed, 1.0)).xyz;',
        );
    };
    const key = material.customProgramCacheKey.bind(material);
    material.customProgramCacheKey = () => `${key()} quatcurve-bones ${this.wrapOpen}`;
    if (this.wrapOpen) material.defines = { ...material.defines, QUATCURVE_WRAP_OPEN: '' };
    material.needsUpdate = true;
    return material;
  }
}

/** The sidecar's layout fields as three.js sets a struct uniform: vectors as THREE.Vector4. */
function layoutValue(fields) {
  const value = {};
  for (const [key, v] of Object.entries(fields)) {
    value[key] = Array.isArray(v) && Array.isArray(v[0]) ? v.map((c) => new THREE.Vector4(...c)) : v;
  }
  return value;
}
