// An FBX as three.js plays it (FBXLoader, AnimationMixer), an independent reader of the FBX
// beside quatcurve's bake of it (URL parameters):
// - mode=joints (source=FBX, bake=SIDECAR): for each of the sidecar's clips, at each of its
//   frames (time start + f / rate, the source's clock), the world position of every sidecar
//   joint three.js has an object for (names as three.js sanitizes them), in the FBX's units.
// - mode=silhouette (source=FBX, glb=BAKED_GLB, bake=SIDECAR, similarity=s,r00,...,r22,tx,ty,tz):
//   for each clip at four of its frames, the FBX's skinned meshes placed by the similarity (its units
//   and axes to the bake's) against the baked .glb's played by three.js's GLTFLoader and
//   AnimationMixer, both drawn white on black from one camera. break=time poses the .glb a quarter of the clip
//   later.
import * as THREE from 'three';
import { frame, mask, mismatch } from '/common/masks.js';
import { FBXLoader } from 'three/addons/loaders/FBXLoader.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const params = new URLSearchParams(location.search);
const SIZE = 256;
// The fractions of each clip's span the silhouettes are compared at.
const FRACTIONS = [0.1, 0.35, 0.6, 0.85];

window.quatcurveTest = (async () => {
  const mode = params.get('mode');
  if (mode === 'joints') return joints();
  if (mode === 'silhouette') return silhouettes();
  throw new Error(`mode ${mode}?`);
})();

// A texel, for the texture files an FBX names beside itself (Blender's `NAME.fbm/`): the
// silhouettes are drawn white, and a missing file would be a page error.
const TEXEL = 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8/5+hHgAHggJ/PchI7wAAAABJRU5ErkJggg==';

/** The FBX's scene and a mixer on it, and the bake's sidecar. */
async function load() {
  const source = params.get('source');
  const manager = new THREE.LoadingManager();
  manager.setURLModifier((url) => (url.endsWith(source) || url.startsWith('blob:') || url.startsWith('data:') ? url : TEXEL));
  const fbx = await new FBXLoader(manager).loadAsync(source);
  const sidecar = await (await fetch(params.get('bake'))).json();
  return { fbx, sidecar, mixer: new THREE.AnimationMixer(fbx) };
}

/** A function posing `root` through `mixer` at a time of `animation`. */
function poser(mixer, root, animation) {
  mixer.stopAllAction();
  const action = mixer.clipAction(animation);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.reset().play();
  return (time) => {
    action.time = time;
    mixer.update(0);
    root.updateMatrixWorld(true);
  };
}

/**
 * The animation a sidecar clip was baked from: by name (three.js names an FBX stack as the
 * file does, `object|action` from Blender, where the bake names the action), else by index.
 */
function animationOf(animations, clip, index) {
  return animations.find((a) => a.name === clip.name || a.name.endsWith(`|${clip.name}`)) ?? animations[index];
}

async function joints() {
  const { fbx, sidecar, mixer } = await load();
  const names = sidecar.joints.map((n) => THREE.PropertyBinding.sanitizeNodeName(n));
  const objects = names.map((n) => fbx.getObjectByName(n));
  const found = sidecar.joints.filter((_, j) => objects[j]);
  const clips = [];
  for (const [c, clip] of sidecar.clips.entries()) {
    const animation = animationOf(fbx.animations, clip, c);
    const pose = poser(mixer, fbx, animation);
    const frames = [];
    for (let f = 0; f < clip.frames; f++) {
      pose(clip.start + f / clip.rate);
      const p = new THREE.Vector3();
      frames.push(objects.filter(Boolean).map((o) => o.getWorldPosition(p).toArray()));
    }
    clips.push({ name: clip.name, animation: animation.name, frames });
  }
  return { joints: found, clips };
}

async function silhouettes() {
  const { fbx, sidecar, mixer } = await load();
  const [s, ...rest] = params.get('similarity').split(',').map(Number);
  const [r, t] = [rest.slice(0, 9), rest.slice(9, 12)];
  const placed = new THREE.Group();
  placed.matrixAutoUpdate = false;
  placed.matrix.set(s * r[0], s * r[1], s * r[2], t[0], s * r[3], s * r[4], s * r[5], t[1],
    s * r[6], s * r[7], s * r[8], t[2], 0, 0, 0, 1);
  placed.add(fbx);
  const gltf = await new GLTFLoader().loadAsync(params.get('glb'));
  const white = new THREE.MeshBasicMaterial({ color: 0xffffff, side: THREE.DoubleSide });
  // The skinned meshes drawn (Blender's exports carry a static Icosphere round the character).
  for (const root of [fbx, gltf.scene]) {
    root.traverse((o) => {
      if (o.isMesh) o.material = white;
      if (o.isMesh && !o.isSkinnedMesh) o.visible = false;
    });
  }
  const source = new THREE.Scene();
  source.add(placed);
  const baked = new THREE.Scene();
  baked.add(gltf.scene);
  const bakedMixer = new THREE.AnimationMixer(gltf.scene);

  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setSize(SIZE, SIZE, false);
  renderer.setClearColor(0x000000);
  document.body.appendChild(renderer.domElement);
  const camera = new THREE.PerspectiveCamera(30, 1, 0.01, 1000);
  const results = [];
  for (const [c, clip] of sidecar.clips.entries()) {
    const poseSource = poser(mixer, source, animationOf(fbx.animations, clip, c));
    const poseBaked = poser(bakedMixer, gltf.scene, animationOf(gltf.animations, clip, c));
    const span = (clip.frames - 1) / clip.rate;
    poseBaked(clip.start + FRACTIONS[0] * span);
    // Framed on the skinned meshes: a file's other objects (lights, helpers) may be far off.
    const box = new THREE.Box3();
    gltf.scene.traverse((o) => { if (o.isSkinnedMesh) box.expandByObject(o, true); });
    frame(camera, box, new THREE.Vector3(1, 0.25, 0.6));
    for (const fraction of FRACTIONS) {
      // A baked frame's time: the bake is the source there (between frames, the baked file
      // is its frames interpolated, the source its keys).
      const time = clip.start + Math.round(fraction * (clip.frames - 1)) / clip.rate;
      poseSource(time);
      const expected = mask(renderer, source, camera, SIZE);
      poseBaked(params.get('break') === 'time' ? clip.start + ((fraction + 0.25) % 1) * span : time);
      const got = mask(renderer, baked, camera, SIZE);
      results.push({ clip: clip.name, time, ...mismatch(expected, got) });
    }
  }
  return { results };
}

