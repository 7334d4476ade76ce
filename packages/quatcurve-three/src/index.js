// quatcurve-three: plays a quatcurve bake in three.js as an instanced crowd, each instance
// with its own clip, time offset and speed, animated on the GPU from the bake's textures
// (skin-trs bone textures: skinned; vertex textures: each vertex read) by the shader library
// `quatcurve shaders --library` generates (bones.glsl, vertex.glsl, beside this file), inside
// the user's own material. Everything the shader needs comes from the bake's sidecar: the
// files, each texture's layout uniform by name, the clips.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { decodePng16 } from './png16.js';

// How each texture kind plays: its library, the declarations and calls it needs inside
// three.js's vertex shader (at the start of main, after the normal is read, after the
// position is read), and its layout uniform.
const KINDS = {
  'skin-trs': {
    library: new URL('./bones.glsl', import.meta.url),
    layout: 'bone_layout',
    declarations: /* glsl */ `
in vec4 skinIndex;
in vec4 skinWeight;`,
    main: /* glsl */ `
	mat4 quatcurveSkin = bone_skin_matrix(quatcurveClip, uvec4(skinIndex + 0.5), skinWeight, quatcurveClipTime);`,
    normal: /* glsl */ `
	objectNormal = (quatcurveSkin * vec4(objectNormal, 0.0)).xyz;`,
    position: /* glsl */ `
	transformed = (quatcurveSkin * vec4(transformed, 1.0)).xyz;`,
  },
  vertex: {
    library: new URL('./vertex.glsl', import.meta.url),
    layout: 'vertex_layout',
    declarations: '',
    // The mesh file's TEXCOORD_0 (three.js's `uv`) is the vertex's texel in a frame.
    main: /* glsl */ `
	uvec2 quatcurveAddress = uvec2(uv + 0.5);`,
    normal: /* glsl */ `
	if (vertex_layout.has_normals != 0u) objectNormal = vertex_normal(quatcurveClip, quatcurveAddress, quatcurveClipTime);`,
    position: /* glsl */ `
	transformed = vertex_position(quatcurveClip, quatcurveAddress, quatcurveClipTime);`,
  },
};

// The per-instance inputs, the crowd's clock, and the time an instance is at in its clip;
// LAYOUT is the kind's layout uniform.
const INSTANCE = /* glsl */ `
// Per instance: its clip (an index into the layout's clips), time offset (s) and speed.
in vec3 quatcurveInstance;
uniform float quatcurveTime;
float quatcurveTimeIn(uint clip) {
  float time = quatcurveTime * quatcurveInstance.z + quatcurveInstance.y;
#ifdef QUATCURVE_WRAP_OPEN
  BoneClip c = LAYOUT.clips[clip];
  float span = float(max(c.frames, 1u) - 1u) / c.rate;
  if (c.looping == 0u && span > 0.0) time -= floor(time / span) * span;
#endif
  return time;
}`;
const MAIN = /* glsl */ `
	uint quatcurveClip = uint(quatcurveInstance.x + 0.5);
	float quatcurveClipTime = quatcurveTimeIn(quatcurveClip);`;

/**
 * A bake loaded: its sidecar, its meshes and its textures.
 * @typedef {object} Bake
 * @property {object} sidecar the sidecar JSON as the bake wrote it
 * @property {string[]} clips clip names, in the sidecar's order
 * @property {{geometry: THREE.BufferGeometry, material: THREE.Material, name: string}[]} meshes the
 *   skinned meshes (bind pose) or the vertex bake's mesh file's primitives
 * @property {Map<string, THREE.DataTexture>} textures the textures by file name, rows top-down
 * @property {THREE.Box3} box where a character stands in the scene's units: its bind pose (a
 *   vertex bake's: the box its first clip moves in), for spacing a crowd and framing a camera
 * @property {(options?: CrowdOptions) => Crowd} createCrowd
 */

/**
 * Loads the bake whose sidecar is at `sidecarUrl` (`quatcurve bake --texture skin-trs` or
 * `--texture vertex`, of `--format exr` or `png16`): the sidecar, the mesh (the baked glTF,
 * or a vertex bake's mesh file, through three.js's GLTFLoader) and every texture (EXRLoader,
 * rows put back top-down; PNG16 decoded to 16 bits).
 * @param {string | URL} sidecarUrl
 * @param {{manager?: THREE.LoadingManager}} [options]
 * @returns {Promise<Bake>}
 */
export async function loadBake(sidecarUrl, { manager } = {}) {
  const url = new URL(sidecarUrl, globalThis.location?.href);
  const sidecar = await fetchOk(url).then((r) => r.json());
  const name = url.pathname.split('/').pop();
  const kind = KINDS[sidecar.texture];
  if (!kind || !['exr', 'png16'].includes(sidecar.format)) {
    throw new Error(
      `${name}: a ${sidecar.texture} bake of ${sidecar.format} files; quatcurve-three plays ` +
        '`quatcurve bake --texture skin-trs` or `--texture vertex` bakes of `--format exr` or png16',
    );
  }
  const vertex = sidecar.texture === 'vertex';
  const meshFile = vertex ? sidecar.vertex?.mesh_file : sidecar.baked_file;
  if (!meshFile) throw new Error(`${name}: names no mesh (baked_file, vertex.mesh_file)`);
  const loader = new GLTFLoader(manager);
  // A vertex bake's mesh file has no materials: they, and the UVs they are mapped with, come
  // from the baked glTF beside it (the source's meshes, vertex for vertex).
  const [library, gltf, baked] = await Promise.all([
    fetchOk(kind.library).then((r) => r.text()),
    loader.loadAsync(new URL(meshFile, url).href),
    vertex && sidecar.baked_file ? loader.loadAsync(new URL(sidecar.baked_file, url).href) : null,
  ]);
  const meshes = vertex ? vertexMeshes(gltf, sidecar, meshFile, baked) : skinnedMeshes(gltf, sidecar, name);
  const textures = new Map();
  const loading = sidecar.textures.map(async (record) => {
    textures.set(record.file, await imageTexture(new URL(record.file, url), record, sidecar, manager));
  });
  await Promise.all(loading);
  const box = new THREE.Box3();
  for (const mesh of meshes) box.union(mesh.box);
  const bake = { sidecar, clips: sidecar.clips.map((c) => c.name), meshes, textures, library, kind, box };
  bake.createCrowd = (options) => new Crowd(bake, options);
  return bake;
}

async function fetchOk(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: ${response.status} ${response.statusText}`);
  return response;
}

/**
 * Every primitive the bake's skin textures draw, in bind space, with its skin's index in the
 * file: the glTF's skinned meshes, and its rigid parts (meshes hung from a joint without a
 * skin) bound to their joint as the sidecar's `primitives` say.
 */
function skinnedMeshes(gltf, sidecar, name) {
  const { parser } = gltf;
  const found = [];
  gltf.scene.updateMatrixWorld(true);
  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    // The glTF node of the mesh (a multi-primitive mesh is a group of meshes under it).
    let node = object;
    while (node && parser.associations.get(node)?.nodes === undefined) node = node.parent;
    const index = node ? parser.associations.get(node).nodes : undefined;
    let geometry = object.geometry;
    let skin;
    if (object.isSkinnedMesh) {
      skin = index === undefined ? undefined : parser.json.nodes[index].skin;
      if (skin === undefined) throw new Error(`${name}: skinned mesh ${object.name} has no glTF skin`);
      if (!geometry.attributes.skinIndex || !geometry.attributes.skinWeight) {
        throw new Error(`${name}: mesh ${object.name} has no JOINTS_0 and WEIGHTS_0`);
      }
    } else {
      const primitive = parser.associations.get(object)?.primitives ?? 0;
      const part = sidecar.primitives?.find((p) => p.rigid && p.node === index && p.primitive === primitive);
      // A mesh the sidecar does not bind is in its `not_drawn`.
      if (!part) return;
      skin = part.skin;
      geometry = rigidGeometry(object, part.rigid);
    }
    // Lit materials need normals; a mesh without them gets its bind pose's.
    if (!geometry.attributes.normal) geometry.computeVertexNormals();
    // The bind pose in the scene: glTF skinning takes a vertex to where the mesh's node puts it.
    object.geometry.computeBoundingBox();
    const box = object.geometry.boundingBox.clone().applyMatrix4(object.matrixWorld);
    found.push({ geometry, material: object.material, name: object.name, files: (clip) => [clip.files[skin]], box });
  });
  if (!found.length) throw new Error(`${name}: the baked glTF has no skinned mesh`);
  return found;
}

/**
 * A rigid part's geometry as a skinned mesh's: its morph targets at the mesh's weights, taken
 * into its skin's bind space by the sidecar's `bind` (3x4 row-major), and bound to its joint
 * alone.
 */
function rigidGeometry(object, { joint, bind }) {
  const geometry = object.geometry.clone();
  const influences = object.morphTargetInfluences ?? [];
  for (const [attribute, targets] of Object.entries(geometry.morphAttributes)) {
    const values = geometry.attributes[attribute];
    if (!values) continue;
    targets.forEach((target, t) => {
      const weight = influences[t] ?? 0;
      if (weight === 0) return;
      // glTF's morph targets are deltas (three.js's morphTargetsRelative).
      for (let i = 0; i < values.array.length; i++) values.array[i] += weight * target.array[i];
    });
  }
  geometry.morphAttributes = {};
  const m = new THREE.Matrix4().set(...bind, 0, 0, 0, 1);
  geometry.applyMatrix4(m);
  const count = geometry.attributes.position.count;
  const joints = new Uint16Array(4 * count);
  const weights = new Float32Array(4 * count);
  for (let v = 0; v < count; v++) {
    joints[4 * v] = joint;
    weights[4 * v] = 1;
  }
  geometry.setAttribute('skinIndex', new THREE.BufferAttribute(joints, 4));
  geometry.setAttribute('skinWeight', new THREE.BufferAttribute(weights, 4));
  return geometry;
}

/** Every primitive of a vertex bake's mesh file, with the sheets its clips' files name. */
function vertexMeshes(gltf, sidecar, file, baked) {
  const found = [];
  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    const k = gltf.parser.associations.get(object)?.meshes;
    const primitive = sidecar.vertex.primitives.find((p) => p.mesh_in_file === k);
    if (!primitive) throw new Error(`${file}: mesh ${k} is no primitive of the sidecar's vertex record`);
    const sheet = (clip, part) => clip.files.find((f) => f.includes(`${primitive.suffix}.${part}.`));
    // The positions' file carries the layout; the normals' (when the primitive has them) goes with it.
    const files = (clip) => [sheet(clip, 'pos'), sheet(clip, 'nrm')];
    // The box every frame's positions are remapped into (its first clip's file's).
    const record = sidecar.textures.find((t) => t.file === files(sidecar.clips[0])[0]);
    const [low, span] = [new THREE.Vector3(...record.low), new THREE.Vector3(...record.span)];
    const box = new THREE.Box3(low, low.clone().add(span));
    const { geometry } = object;
    const material = baked ? texturedFrom(baked, primitive, geometry) : object.material;
    // Without normals three.js lights the faces (flat shading).
    found.push({ geometry, material, name: primitive.name, files, normals: primitive.normals, box });
  });
  if (!found.length) throw new Error(`${file}: no mesh`);
  return found;
}

// The material slots three.js maps with a texture coordinate.
const MAPS = ['map', 'alphaMap', 'aoMap', 'bumpMap', 'emissiveMap', 'lightMap', 'metalnessMap', 'normalMap', 'roughnessMap'];

/**
 * The baked glTF's material of a vertex bake's `primitive`, its textures read through the
 * source's TEXCOORD_0 given to `geometry` as `uv1` (its `uv` is each vertex's texel address).
 */
function texturedFrom(baked, primitive, geometry) {
  let source = null;
  baked.scene.traverse((object) => {
    const at = baked.parser.associations.get(object);
    if (object.isMesh && at?.meshes === primitive.mesh && (at.primitives ?? 0) === primitive.primitive) source = object;
  });
  if (!source) throw new Error(`${primitive.name}: not in the baked glTF`);
  const uv = source.geometry.attributes.uv;
  const material = source.material.clone();
  if (uv && uv.count === geometry.attributes.position.count) {
    geometry.setAttribute('uv1', uv);
    for (const slot of MAPS) {
      if (material[slot]) {
        material[slot] = material[slot].clone();
        material[slot].channel = 1;
      }
    }
  } else {
    for (const slot of MAPS) material[slot] = null;
  }
  return material;
}

/** A texture as the library samples it: RGBA floats, texel by texel, rows top-down. */
async function imageTexture(url, record, sidecar, manager) {
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
 * An instanced crowd of one bake: a THREE.Group of one InstancedMesh per primitive
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
   * and transform in the crowd. It shows its clip at `seconds * speed + offset` on the
   * source's clock, as three.js's `AnimationMixer` plays the source (a clip whose first key is
   * past 0 holds its first frame until then).
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

  /** Each instance into the InstancedMesh of its clip's texture, for every mesh. */
  fill() {
    const { sidecar, meshes } = this.bake;
    const slots = new Map();
    for (const part of this.parts.values()) part.mesh.count = 0;
    for (const [m, mesh] of meshes.entries()) {
      for (const instance of this.instances) {
        const clip = sidecar.clips[instance.clip];
        const [file, ...others] = mesh.files(clip);
        const record = sidecar.textures.find((t) => t.file === file);
        const at = record?.layout?.clips.indexOf(instance.clip) ?? -1;
        if (at < 0) throw new Error(`${file}: its layout holds no clip ${clip.name}`);
        const part = this.part(m, mesh, record, others);
        const slot = slots.get(part) ?? 0;
        slots.set(part, slot + 1);
        part.mesh.setMatrixAt(slot, instance.matrix);
        // The shader's time counts from the clip's first frame; an instance's, as three.js's
        // AnimationMixer counts it, from the source's time zero.
        part.attribute.setXYZ(slot, at, instance.offset - clip.start, instance.speed);
      }
    }
    for (const part of this.parts.values()) {
      part.mesh.count = slots.get(part) ?? 0;
      part.mesh.instanceMatrix.needsUpdate = true;
      part.attribute.needsUpdate = true;
    }
    this.dirty = false;
  }

  part(m, mesh, record, others) {
    const key = `${m} ${record.file}`;
    if (!this.parts.has(key)) {
      const geometry = mesh.geometry.clone();
      const attribute = new THREE.InstancedBufferAttribute(new Float32Array(this.count * 3), 3);
      geometry.setAttribute('quatcurveInstance', attribute);
      const material = this.animated(this.materialFor(mesh.material), mesh, record, others);
      const instanced = new THREE.InstancedMesh(geometry, material, this.count);
      // The bind pose's bounds say nothing of where an animated instance is.
      instanced.frustumCulled = false;
      instanced.name = `${mesh.name} ${record.file}`;
      this.add(instanced);
      this.parts.set(key, { mesh: instanced, attribute });
    }
    return this.parts.get(key);
  }

  /** `material` animated by the library from the texture of `record` (and `others`). */
  animated(material, mesh, record, others) {
    const { kind, library, textures } = this.bake;
    const layout = record.layout;
    const uniforms = { [layout.variable]: { value: layoutValue(layout.fields) }, quatcurveTime: this.time };
    if (layout.variable === 'bone_layout') {
      uniforms.bone_texture = { value: textures.get(record.file) };
    } else {
      // Without a normals' file the positions stand in for its binding (the layout says none).
      uniforms.vertex_positions = { value: textures.get(record.file) };
      uniforms.vertex_normals = { value: textures.get(others[0] ?? record.file) };
      if (!mesh.normals) material.flatShading = true;
    }
    const instance = INSTANCE.replace('LAYOUT', kind.layout);
    const previous = material.onBeforeCompile;
    material.onBeforeCompile = (shader, renderer) => {
      previous?.call(material, shader, renderer);
      Object.assign(shader.uniforms, uniforms);
      shader.vertexShader = shader.vertexShader
        .replace('#include <common>', `#include <common>\n${library}\n${kind.declarations}\n${instance}`)
        .replace('void main() {', `void main() {${MAIN}${kind.main}`)
        .replace('#include <beginnormal_vertex>', `#include <beginnormal_vertex>${kind.normal}`)
        .replace('#include <begin_vertex>', `#include <begin_vertex>${kind.position}`);
    };
    const key = material.customProgramCacheKey.bind(material);
    material.customProgramCacheKey = () => `${key()} quatcurve ${layout.variable} ${this.wrapOpen}`;
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
