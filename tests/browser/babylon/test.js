// What the Babylon.js tests measure in the browser (URL parameters; bake=SIDECAR of a
// `--texture skin --format babylon` bake, source=GLB it was baked from):
// - mode=silhouette (cycles=C): for each clip at four of its frames, the silhouette of the
//   baked glTF played by Babylon's own BakedVertexAnimationManager from the bake's JSON with the
//   sidecar's settings, C periods on for a loop (an open clip in its first cycle), against
//   Babylon playing the source .glb's animation group at that frame's time, both white on black
//   from one camera. break=time plays every frame at the clip's first; break=space multiplies
//   each bone by its mesh parent's world matrix (skin matrices in the glTF's world, as a `skin`
//   texture holds them, not in the space Babylon draws the mesh in); break=period plays a loop
//   with a frame a row (first_row to its last row at the clip's rate, as if Babylon's cycle
//   were the clip's period).
// - mode=baker: each clip baked by Babylon's own VertexAnimationBaker at the bake's frame
//   times (the group's animations moved onto the bones, which is what that baker plays),
//   against the bake's JSON as Babylon's loadBakedVertexDataFromJSON reads it: the largest
//   difference of any matrix entry, rotation part and translation apart, and the same against
//   the next frame (what a one-frame slip would show).
const B = window.BABYLON;
const params = new URLSearchParams(location.search);
const SIZE = 256;
// The fractions of each clip's frames the silhouettes are compared at.
const FRACTIONS = [0.1, 0.35, 0.6, 0.85];
// GLTFLoaderAnimationStartMode.NONE: the loader leaves every animation group stopped.
const NO_ANIMATION = { pluginOptions: { gltf: { animationStartMode: 0 } } };

window.quatcurveTest = (async () => {
  const mode = params.get('mode');
  if (mode === 'silhouette') return silhouettes();
  if (mode === 'baker') return baker();
  throw new Error(`mode ${mode}?`);
})();

/** The sidecar at `url` and a reader of the files beside it. */
async function loadBake(url) {
  const sidecar = await (await fetch(url)).json();
  const beside = (file) => new URL(file, new URL(url, location.href)).href;
  return { sidecar, beside, text: async (file) => (await fetch(beside(file))).text() };
}

/** The skinned meshes of a load, each with its skin's index in the sidecar. */
function skinnedMeshes(loaded, sidecar) {
  return loaded.meshes
    .filter((m) => m.skeleton && m.getTotalVertices() > 0)
    .map((mesh) => {
      // Babylon names a skeleton after its skin, as the sidecar names the skin.
      const skin = sidecar.skins.findIndex((s) => s.name === mesh.skeleton.name);
      if (skin < 0) throw new Error(`no skin in the sidecar for skeleton ${mesh.skeleton.name}`);
      return { mesh, skin };
    });
}

/** The animation group of clip `c` of the sidecar. */
function groupOf(loaded, sidecar, c) {
  return loaded.animationGroups.find((g) => g.name === sidecar.clips[c].name) ?? loaded.animationGroups[c];
}

/** Babylon's frame (its animations' frame rate) of time `seconds` in the source. */
function frameAt(group, seconds) {
  return seconds * group.targetedAnimations[0].animation.framePerSecond;
}

function newScene() {
  const engine = new B.Engine(document.getElementById('canvas'), false, { preserveDrawingBuffer: true });
  const scene = new B.Scene(engine);
  scene.clearColor = new B.Color4(0, 0, 0, 1);
  return { engine, scene };
}

async function silhouettes() {
  const { engine, scene } = newScene();
  const bake = await loadBake(params.get('bake'));
  const white = new B.StandardMaterial('white', scene);
  white.disableLighting = true;
  white.emissiveColor = B.Color3.White();
  const source = await B.ImportMeshAsync(params.get('source'), scene, NO_ANIMATION);
  const played = await B.ImportMeshAsync(bake.beside(bake.sidecar.baked_file), scene, NO_ANIMATION);
  const sources = skinnedMeshes(source, bake.sidecar);
  const meshes = skinnedMeshes(played, bake.sidecar);
  for (const m of [...sources, ...meshes]) {
    m.mesh.material = white;
    m.mesh.alwaysSelectAsActiveMesh = true;
  }
  const show = (which) => {
    for (const m of sources) m.mesh.setEnabled(which === sources);
    for (const m of meshes) m.mesh.setEnabled(which === meshes);
  };
  const camera = new B.FreeCamera('camera', new B.Vector3(0, 0, -10), scene);
  camera.fov = Math.PI / 6;

  const results = [];
  for (const [c, clip] of bake.sidecar.clips.entries()) {
    // Each mesh plays its skin's file of this clip, as a user's page would.
    for (const { mesh, skin } of meshes) {
      const baker = new B.VertexAnimationBaker(scene, mesh);
      const data = baker.loadBakedVertexDataFromJSON(await bake.text(clip.files[skin]));
      if (params.get('break') === 'space') toWorld(data, mesh);
      mesh.bakedVertexAnimationManager?.texture?.dispose();
      const manager = new B.BakedVertexAnimationManager(scene);
      manager.texture = baker.textureFromBakedVertexData(data);
      const settings = params.get('break') === 'period'
        ? [clip.first_row, clip.first_row + clip.frames - 1, 0, clip.rate]
        : bake.sidecar.babylon.clips[c];
      manager.animationParameters = new B.Vector4(...settings);
      mesh.bakedVertexAnimationManager = manager;
    }
    const group = groupOf(source, bake.sidecar, c);
    group.play(false);
    group.pause();
    for (const [k, fraction] of FRACTIONS.entries()) {
      const row = Math.round(fraction * (clip.frames - 1));
      const time = clip.start + row / clip.rate;
      group.goToFrame(frameAt(group, time));
      if (k === 0) frame(camera, sources.map((m) => m.mesh));
      show(sources);
      const expected = await mask(engine, scene);
      // The middle of the row's frame (the manager floors), `cycles` periods on for a loop.
      const played = params.get('break') === 'time' ? 0 : row;
      const cycles = clip.loop ? Number(params.get('cycles') ?? 1) : 0;
      const seconds = (cycles * (clip.frames - 1) + played + 0.5) / clip.rate;
      for (const { mesh } of meshes) mesh.bakedVertexAnimationManager.time = seconds;
      show(meshes);
      const got = await mask(engine, scene);
      let either = 0;
      let one = 0;
      for (let i = 0; i < expected.length; i++) {
        either += expected[i] || got[i];
        one += expected[i] !== got[i];
      }
      results.push({ clip: clip.name, time: row / clip.rate, mismatch: one / Math.max(either, 1), pixels: either });
    }
    group.stop();
  }
  return { renderer: engine.getGlInfo().renderer, results };
}

/** Each bone's matrix of `data` times the world matrix (in the glTF's space) of `mesh`'s parent. */
function toWorld(data, mesh) {
  // Babylon's world of the parent is the glTF's times the loader's __root__ (handedness).
  const root = rootOf(mesh).computeWorldMatrix(true).clone().invert();
  const parent = mesh.parent.computeWorldMatrix(true).multiply(root);
  for (let at = 0; at < data.length; at += 16) {
    B.Matrix.FromArray(data, at).multiply(parent).copyToArray(data, at);
  }
}

function rootOf(node) {
  while (node.parent) node = node.parent;
  return node;
}

/** Points `camera` at the meshes' skinned bounding box from the front, the whole box in view. */
function frame(camera, meshes) {
  let min = new B.Vector3(Infinity, Infinity, Infinity);
  let max = min.negate();
  for (const mesh of meshes) {
    mesh.refreshBoundingInfo({ applySkeleton: true });
    const box = mesh.getBoundingInfo().boundingBox;
    min = B.Vector3.Minimize(min, box.minimumWorld);
    max = B.Vector3.Maximize(max, box.maximumWorld);
  }
  const centre = min.add(max).scale(0.5);
  const size = max.subtract(min).length();
  camera.position = centre.add(new B.Vector3(0.3, 0.2, -1).normalize().scale(size * 2.2));
  camera.minZ = size / 100;
  camera.maxZ = size * 10;
  camera.setTarget(centre);
}

/** The pixels the enabled meshes cover, once their shaders are compiled. */
async function mask(engine, scene) {
  await scene.whenReadyAsync();
  scene.render();
  const pixels = await engine.readPixels(0, 0, SIZE, SIZE);
  const covered = new Uint8Array(SIZE * SIZE);
  for (let i = 0; i < covered.length; i++) covered[i] = pixels[i * 4] > 127 ? 1 : 0;
  return covered;
}

async function baker() {
  const { engine, scene } = newScene();
  new B.FreeCamera('camera', new B.Vector3(0, 0, -10), scene);
  const bake = await loadBake(params.get('bake'));
  const source = await B.ImportMeshAsync(params.get('source'), scene, NO_ANIMATION);
  const results = [];
  for (const { mesh, skin } of skinnedMeshes(source, bake.sidecar)) {
    const bones = mesh.skeleton.bones;
    const nodes = bones.map((b) => b.getTransformNode());
    for (const [c, clip] of bake.sidecar.clips.entries()) {
      // VertexAnimationBaker plays the skeleton's own animations: the group's, moved onto the
      // bones from the nodes they drive (Babylon's glTF loader animates the nodes), keyed from
      // the clip's first frame so that its frames are whole ones (the baker's synchronous path,
      // the one that renders each frame before reading it, floors fractional frames).
      const group = groupOf(source, bake.sidecar, c);
      const first = frameAt(group, clip.start);
      const step = frameAt(group, 1 / clip.rate);
      for (const [i, bone] of bones.entries()) {
        bone.animations = group.targetedAnimations
          .filter((t) => t.target === nodes[i])
          .map((t) => {
            const animation = t.animation.clone();
            animation.setKeys(t.animation.getKeys().map((key) => ({ ...key, frame: (key.frame - first) / step })));
            animation.framePerSecond = clip.rate;
            return animation;
          });
        bone.linkTransformNode(null);
      }
      const vatBaker = new B.VertexAnimationBaker(scene, mesh);
      const theirs = vatBaker.bakeVertexDataSync([{ from: 0, to: clip.frames - 1 }], false);
      const ours = vatBaker.loadBakedVertexDataFromJSON(await bake.text(clip.files[skin]));
      const perFrame = (bones.length + 1) * 16;
      const at = (frameIndex) => ours.subarray((clip.first_row + frameIndex) * perFrame, (clip.first_row + frameIndex + 1) * perFrame);
      const compare = (shift) => {
        let rotation = 0;
        let translation = 0;
        for (let f = 0; f + shift < clip.frames; f++) {
          const mine = at(f + shift);
          const babylon = theirs.subarray(f * perFrame, (f + 1) * perFrame);
          for (let i = 0; i < perFrame; i++) {
            const d = Math.abs(mine[i] - babylon[i]);
            if (i % 16 >= 12) translation = Math.max(translation, d);
            else rotation = Math.max(rotation, d);
          }
        }
        return { rotation, translation };
      };
      results.push({
        clip: clip.name,
        skin,
        frames: theirs.length / perFrame,
        same: compare(0),
        next: compare(1),
      });
    }
    nodes.forEach((node, i) => bones[i].linkTransformNode(node));
  }
  return { results, size: sizeOf(source.meshes) };
}

/** The diagonal of the meshes' bounding box at rest. */
function sizeOf(meshes) {
  let min = new B.Vector3(Infinity, Infinity, Infinity);
  let max = min.negate();
  for (const mesh of meshes.filter((m) => m.getTotalVertices() > 0)) {
    const box = mesh.getBoundingInfo().boundingBox;
    min = B.Vector3.Minimize(min, box.minimum);
    max = B.Vector3.Maximize(max, box.maximum);
  }
  return max.subtract(min).length();
}
