// A character from code in a three.js scene. `Character.create()` with no options loads the
// shipped database and avatar: vite finds them (and the WASM core) through the package's
// `new URL('…', import.meta.url)` references and copies them into dist/ by itself.
import * as THREE from 'three';
import { Character } from 'mm-avatar';

const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(devicePixelRatio);
renderer.setSize(innerWidth, innerHeight);
document.body.append(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2126);
scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 2.5));
const sun = new THREE.DirectionalLight(0xffffff, 2);
sun.position.set(3, 6, 4);
scene.add(sun, new THREE.GridHelper(20, 20, 0x556070, 0x333a44));

const camera = new THREE.PerspectiveCamera(45, innerWidth / innerHeight, 0.1, 100);
camera.position.set(2.5, 1.8, 5);

const status = document.getElementById('status')!;
const character = await Character.create({ onProgress: (p) => (status.textContent = `Loading ${p.stage}… ${(p.loaded / 1e6).toFixed(1)} MB`) });
scene.add(character.object3d);
status.textContent = 'Click the floor to walk there.';
// For the console (and the tests): `character.walkTo(3, 2)`.
Object.assign(window, { character });

// A click on the floor walks there.
const raycaster = new THREE.Raycaster();
const floor = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);
renderer.domElement.addEventListener('click', (e) => {
  raycaster.setFromCamera(new THREE.Vector2((e.clientX / innerWidth) * 2 - 1, -(e.clientY / innerHeight) * 2 + 1), camera);
  const hit = raycaster.ray.intersectPlane(floor, new THREE.Vector3());
  if (hit) character.walkTo(hit.x, hit.z);
});

addEventListener('resize', () => {
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(innerWidth, innerHeight);
});

const clock = new THREE.Clock();
const target = new THREE.Vector3();
renderer.setAnimationLoop(() => {
  character.update(Math.min(clock.getDelta(), 0.1));
  const root = character.root;
  camera.lookAt(target.set(root.x, 1, root.z));
  renderer.render(scene, camera);
});
