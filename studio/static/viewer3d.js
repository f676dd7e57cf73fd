// The studio's 3D view: one three.js renderer on a canvas, orbit and zoom, GLB loading, draw on demand.
// Used by the gallery (view.js) and the painter (paint.js). three.js is served by the studio itself
// from the npm package installed in studio/web (see the page's import map); nothing comes from a CDN.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
// Assets exported with export.compression: meshopt (EXT_meshopt_compression) need meshopt's decoder.
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

export { THREE };

// Background of every 3D view; the browser tests count pixels that differ from it.
export const BACKGROUND = '#1d2129';

const LOD = /_LOD(\d+)$/;
const COLLISION = /(^UCX_)|(_collider(_\d+)?$)|(-colonly\d*$)|(_collision(_\d+)?$)/;

// Engine-profile node names (pipeline/engines.py): the LOD level of a node, or -1 for collision meshes.
export function nodeRole(name) {
  if (COLLISION.test(name)) return { collision: true, lod: 0 };
  const m = LOD.exec(name);
  return { collision: false, lod: m ? Number(m[1]) : 0 };
}

// GLB vertex colours are the palette's sRGB bytes (pipeline/palette.py); three.js reads COLOR_0 as linear,
// so convert them once to show the palette's own colours, as the build's preview PNGs do.
function matte(root) {
  root.traverse((o) => {
    if (!o.isMesh) return;
    const color = o.geometry.getAttribute('color');
    if (color && !o.geometry.userData.srgbDone) {
      const c = new THREE.Color();
      for (let i = 0; i < color.count; i++) {
        c.setRGB(color.getX(i), color.getY(i), color.getZ(i), THREE.SRGBColorSpace);
        color.setXYZ(i, c.r, c.g, c.b);
      }
      color.needsUpdate = true;
      o.geometry.userData.srgbDone = true;
    }
    o.material = new THREE.MeshStandardMaterial({
      vertexColors: !!color, color: color ? 0xffffff : 0xb8b8b8, metalness: 0.0, roughness: 0.85,
    });
  });
}

export class Viewer {
  constructor(canvas) {
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(BACKGROUND);
    this.camera = new THREE.PerspectiveCamera(35, 1, 0.001, 1000);
    this.scene.add(this.camera);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x3a3f4a, 1.5));
    const key = new THREE.DirectionalLight(0xffffff, 2.0);
    key.position.set(1.5, 2.5, 2.0);
    this.camera.add(key);  // the light follows the view, so every side is lit
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.addEventListener('change', () => this.render());
    this.content = new THREE.Group();
    this.scene.add(this.content);
    this.frames = 0;
    this.loader = new GLTFLoader().setMeshoptDecoder(MeshoptDecoder);
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
  }

  resize() {
    const w = this.canvas.clientWidth || 1, h = this.canvas.clientHeight || 1;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  // Draw on the next animation frame (once, however many changes came in): no busy render loop.
  render() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.renderer.render(this.scene, this.camera);
      this.frames += 1;
      if (this.onFrame) this.onFrame(this.frames);
    });
  }

  async loadGLB(url) {
    const gltf = await this.loader.loadAsync(url);
    matte(gltf.scene);
    return gltf.scene;
  }

  // The same from the GLB's bytes (the painter shows exactly the bytes it hashed).
  async parseGLB(bytes) {
    const gltf = await this.loader.parseAsync(bytes, '');
    matte(gltf.scene);
    return gltf.scene;
  }

  // Replace what is shown; frame the camera on it unless keepView (then keep the user's orbit).
  show(object, { keepView = false } = {}) {
    for (const old of [...this.content.children]) {
      this.content.remove(old);
      old.traverse((o) => { if (o.geometry) o.geometry.dispose(); if (o.material) o.material.dispose?.(); });
    }
    if (object) this.content.add(object);
    if (object && !keepView) this.frame();
    this.render();
  }

  frame() {
    const box = new THREE.Box3();
    this.content.traverseVisible((o) => { if (o.isMesh) box.expandByObject(o); });
    if (box.isEmpty()) return;
    const center = box.getCenter(new THREE.Vector3());
    const radius = box.getSize(new THREE.Vector3()).length() / 2 || 1;
    const dist = radius / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2)) * 1.05;
    const dir = new THREE.Vector3(0.9, 0.55, 1.3).normalize();
    this.camera.position.copy(center).addScaledVector(dir, dist);
    this.camera.near = dist / 100;
    this.camera.far = dist * 100;
    this.camera.updateProjectionMatrix();
    this.controls.target.copy(center);
    this.controls.update();
    this.render();
  }
}

// Short human figures.
export function fmtBytes(n) {
  if (n == null) return '';
  return n < 1024 ? `${n} B` : n < 1048576 ? `${(n / 1024).toFixed(1)} KB` : `${(n / 1048576).toFixed(2)} MB`;
}

export function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v == null || v === false) continue;
    if (k === 'class') node.className = v;
    else if (k === 'text') node.textContent = v;
    else if (k.startsWith('on')) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) if (c != null) node.append(c);
  return node;
}

export async function getJSON(url, options) {
  const response = await fetch(url, options);
  const body = await response.json().catch(() => ({ error: `${response.status} ${response.statusText}` }));
  if (!response.ok) throw new Error(body.error || `${response.status}`);
  return body;
}

export function postJSON(url, data) {
  return getJSON(url, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(data) });
}
