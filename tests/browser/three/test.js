// What the quatcurve-three tests measure in the browser (URL parameters):
// - mode=silhouette (bake=SIDECAR, source=GLB): for each clip at five times, the silhouette of
//   one crowd instance against three.js's own AnimationMixer playing the source .glb as a
//   SkinnedMesh, both drawn white on black from one camera. break=rows reverses the texture's
//   rows after loading (what a player that ignores EXRLoader's row order shows); break=time
//   draws every instance at time 0 (a player that ignores time).
// - mode=crowd (bake=SIDECAR, instances=N, frames=K): N instances lit and textured by their
//   glTF materials, each with its clip and phase; K frames timed.
// - mode=refuse (bake=SIDECAR): the message loading a bake the package cannot play throws.
import * as THREE from 'three';
import { frame, mask, mismatch } from '/common/masks.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { loadBake, flipRows } from 'quatcurve-three';

const params = new URLSearchParams(location.search);
const SIZE = 256;
// The fractions of each clip's span the silhouettes are compared at (0.65: in Fox's Run, the
// 0.2 s between two keys where a curve through them parts most from slerp).
const FRACTIONS = [0.1, 0.35, 0.6, 0.65, 0.85];

window.quatcurveTest = (async () => {
  const mode = params.get('mode');
  if (mode === 'silhouette') return silhouettes();
  if (mode === 'crowd') return crowd();
  if (mode === 'refuse') return refusal();
  throw new Error(`mode ${mode}?`);
})();

/** What loading a bake the package cannot play throws (mode=refuse). */
async function refusal() {
  try {
    await loadBake(params.get('bake'));
  } catch (e) {
    return { refused: String(e.message) };
  }
  return { refused: null };
}

function newRenderer(width, height) {
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setSize(width, height, false);
  document.body.appendChild(renderer.domElement);
  return renderer;
}

async function silhouettes() {
  const renderer = newRenderer(SIZE, SIZE);
  renderer.setClearColor(0x000000);
  const white = new THREE.MeshBasicMaterial({ color: 0xffffff });
  const gltf = await new GLTFLoader().loadAsync(params.get('source'));
  gltf.scene.traverse((o) => { if (o.isMesh) o.material = white; });
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const source = new THREE.Scene();
  source.add(gltf.scene);

  const bake = await loadBake(params.get('bake'));
  if (params.get('break') === 'rows') {
    for (const texture of bake.textures.values()) {
      const { data, width, height } = texture.image;
      texture.image.data = flipRows(data, width, height);
      texture.needsUpdate = true;
    }
  }
  const crowd = bake.createCrowd({ count: 1, material: white });
  const played = new THREE.Scene();
  played.add(crowd);

  const results = [];
  const camera = new THREE.PerspectiveCamera(30, 1, 0.01, 1000);
  for (const [c, clip] of bake.sidecar.clips.entries()) {
    const animation = gltf.animations.find((a) => a.name === clip.name) ?? gltf.animations[c];
    mixer.stopAllAction();
    const action = mixer.clipAction(animation);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.reset().play();
    crowd.setInstance(0, { clip: c });
    const span = (clip.frames - 1) / clip.rate;
    // One clock for the mixer and the crowd: the source's (the mixer's own).
    const pose = (time) => {
      action.time = time;
      mixer.update(0);
      gltf.scene.updateMatrixWorld(true);
    };
    // One camera per clip, framing the source at the first compared time.
    pose(clip.start + FRACTIONS[0] * span);
    frame(camera, new THREE.Box3().setFromObject(gltf.scene, true), new THREE.Vector3(0.3, 0.2, 1));
    for (const fraction of FRACTIONS) {
      const time = clip.start + fraction * span;
      pose(time);
      const expected = mask(renderer, source, camera, SIZE);
      crowd.update(params.get('break') === 'time' ? 0 : time);
      const got = mask(renderer, played, camera, SIZE);
      results.push({ clip: clip.name, time, ...mismatch(expected, got) });
    }
  }
  return { renderer: rendererName(renderer), results };
}


function rendererName(renderer) {
  const gl = renderer.getContext();
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  return gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER);
}

async function crowd() {
  const width = 960;
  const height = 540;
  const renderer = newRenderer(width, height);
  renderer.setClearColor(0x9fb4c7);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x665544, 1.5));
  const sun = new THREE.DirectionalLight(0xffffff, 2.5);
  sun.position.set(3, 10, 6);
  scene.add(sun);

  const bake = await loadBake(params.get('bake'));
  const count = Number(params.get('instances') || 100);
  const crowd = bake.createCrowd({ count, wrapOpen: true });
  // A square grid, spaced by the character's size; clips and phases by the golden ratio.
  const size = bake.box.getSize(new THREE.Vector3());
  const step = 1.2 * Math.max(size.x, size.z);
  const columns = Math.ceil(Math.sqrt(count));
  for (let i = 0; i < count; i++) {
    const x = ((i % columns) - (columns - 1) / 2) * step;
    const z = (Math.floor(i / columns) - (columns - 1) / 2) * step;
    const phase = (i * 0.618034) % 1;
    crowd.setInstance(i, {
      clip: i % bake.clips.length,
      offset: phase * 3,
      speed: 0.8 + 0.4 * phase,
      position: new THREE.Vector3(x, 0, z),
    });
  }
  scene.add(crowd);
  const camera = new THREE.PerspectiveCamera(40, width / height, step / 50, step * columns * 10);
  const extent = columns * step;
  camera.position.set(0, extent * 0.45, extent * 0.9);
  camera.lookAt(0, 0, 0);

  const frames = Number(params.get('frames') || 10);
  const gl = renderer.getContext();
  const pixel = new Uint8Array(4);
  const times = [];
  for (let f = 0; f < frames; f++) {
    const start = performance.now();
    crowd.update(1 + f / 30);
    renderer.render(scene, camera);
    // Wait for the frame to be drawn, not only submitted.
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    times.push(performance.now() - start);
  }
  const calls = renderer.info.render.calls;
  // Instanced meshes drawn with a base-colour texture.
  const textured = crowd.children.filter((m) => m.material.map).length;
  return { renderer: rendererName(renderer), instances: count, frame_ms: times, draw_calls: calls, textured };
}
