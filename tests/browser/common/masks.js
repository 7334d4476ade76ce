// What the three.js test pages share (served at /common/): a camera framing a box, and the
// pixels a scene covers drawn white on black.
import * as THREE from 'three';

/** Points `camera` at `box` from `direction` (from the box's centre), the whole box in view. */
export function frame(camera, box, direction) {
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length();
  camera.position.copy(centre).add(direction.clone().normalize().multiplyScalar(size * 2.2));
  camera.near = size / 100;
  camera.far = size * 10;
  camera.lookAt(centre);
  camera.updateProjectionMatrix();
}

/** The pixels `scene` covers (red over half), drawn from `camera` into `renderer`'s `size` square. */
export function mask(renderer, scene, camera, size) {
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const pixels = new Uint8Array(size * size * 4);
  gl.readPixels(0, 0, size, size, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
  const covered = new Uint8Array(size * size);
  for (let i = 0; i < covered.length; i++) covered[i] = pixels[i * 4] > 127 ? 1 : 0;
  return covered;
}

/** The share of the pixels either mask covers that only one does, and how many either covers. */
export function mismatch(expected, got) {
  let either = 0;
  let one = 0;
  for (let i = 0; i < expected.length; i++) {
    either += expected[i] || got[i];
    one += expected[i] !== got[i];
  }
  return { mismatch: one / Math.max(either, 1), pixels: either };
}
