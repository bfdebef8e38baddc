// The scan viewer: a .glb (Draco-compressed, metres) with orbit, texture and wireframe toggles,
// and a two-click distance in millimetres. The first view frames the mesh exactly as
// host/preview's frame_mesh() does (the browser test compares the two).
// URL: view.html?mesh=/share/<patient>/<scan>.glb[&azimuth=DEG]
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';

const FOV_Y_DEG = 30;
const state = { ready: false, error: null, measurement_mm: null, points: [] };
window.facescanView = state;
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const meshUrl = params.get('mesh');
const azimuth = THREE.MathUtils.degToRad(parseFloat(params.get('azimuth') || '0'));

const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1); // one canvas pixel per CSS pixel: clicks and screenshots agree
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202428);
const camera = new THREE.PerspectiveCamera(FOV_Y_DEG, 1, 0.001, 100);
scene.add(camera);
scene.add(new THREE.AmbientLight(0xffffff, 1.2));
const headlight = new THREE.DirectionalLight(0xffffff, 2.0);
camera.add(headlight);
headlight.position.set(0, 0, 1);
const controls = new OrbitControls(camera, canvas);
controls.addEventListener('change', draw);
const markers = new THREE.Group();
scene.add(markers);
let model = null, materials = [], textures = new Map();

function resize() {
	const w = canvas.clientWidth, h = canvas.clientHeight;
	renderer.setSize(w, h, false);
	camera.aspect = w / h;
	camera.updateProjectionMatrix();
	draw();
}
function draw() { renderer.render(scene, camera); }
window.addEventListener('resize', resize);

function fail(msg) {
	state.error = msg;
	$('status').textContent = msg;
}

function frame(object) {
	// Same as preview::frame_mesh: bounding-box centre, bounding sphere filling the vertical fov.
	const box = new THREE.Box3().setFromObject(object);
	const centre = box.getCenter(new THREE.Vector3());
	const radius = box.getSize(new THREE.Vector3()).length() / 2;
	const dist = radius / Math.sin(THREE.MathUtils.degToRad(FOV_Y_DEG) / 2);
	camera.position.set(centre.x + dist * Math.sin(azimuth), centre.y, centre.z + dist * Math.cos(azimuth));
	camera.near = dist / 100;
	camera.far = dist * 10;
	camera.up.set(0, 1, 0);
	camera.lookAt(centre);
	camera.updateProjectionMatrix();
	controls.target.copy(centre);
	controls.update();
	state.markerSize = radius / 150;
}

if (!meshUrl) {
	fail('no mesh given (view.html?mesh=...)');
} else {
	const draco = new DRACOLoader();
	draco.setDecoderPath('/vendor/three/examples/jsm/libs/draco/gltf/');
	draco.setDecoderConfig({ type: 'wasm' });
	const loader = new GLTFLoader();
	loader.setDRACOLoader(draco);
	loader.load(meshUrl, (gltf) => {
		model = gltf.scene;
		model.traverse((o) => {
			if (o.isMesh) {
				materials.push(o.material);
				textures.set(o.material, o.material.map);
			}
		});
		scene.add(model);
		resize();
		frame(model);
		draw();
		const name = decodeURIComponent(meshUrl.split('/').pop());
		$('status').textContent = name;
		document.title = 'facescan: ' + name;
		requestAnimationFrame(() => { draw(); state.ready = true; });
	}, undefined, (e) => fail('cannot load ' + meshUrl + ': ' + (e.message || e)));
}

function toggle(id, on) { $(id).classList.toggle('on', on); }
let textureOn = true, wireframeOn = false, measuring = false;
function setTexture(on) {
	textureOn = on;
	for (const m of materials) { m.map = on ? textures.get(m) : null; m.needsUpdate = true; }
	toggle('texture', on);
	draw();
}
function setWireframe(on) {
	wireframeOn = on;
	for (const m of materials) m.wireframe = on;
	toggle('wireframe', on);
	draw();
}
function setMeasuring(on) {
	measuring = on;
	toggle('measure', on);
	state.points = [];
	state.measurement_mm = null;
	markers.clear();
	$('distance').textContent = on ? 'click two points' : '';
	draw();
}
$('texture').onclick = () => setTexture(!textureOn);
$('wireframe').onclick = () => setWireframe(!wireframeOn);
$('measure').onclick = () => setMeasuring(!measuring);
window.addEventListener('keydown', (e) => {
	if (e.key === 't') setTexture(!textureOn);
	if (e.key === 'w') setWireframe(!wireframeOn);
	if (e.key === 'm') setMeasuring(!measuring);
});

// A click (not a drag of the orbit) in measuring mode picks a surface point.
let down = null;
canvas.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
canvas.addEventListener('pointerup', (e) => {
	if (!measuring || !model || !down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 3) return;
	const rect = canvas.getBoundingClientRect();
	const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1,
		-((e.clientY - rect.top) / rect.height) * 2 + 1);
	const ray = new THREE.Raycaster();
	ray.setFromCamera(ndc, camera);
	const hit = ray.intersectObject(model, true)[0];
	if (!hit) return;
	if (state.points.length === 2) { state.points = []; markers.clear(); }
	state.points.push(hit.point.clone());
	const dot = new THREE.Mesh(new THREE.SphereGeometry(state.markerSize, 12, 8),
		new THREE.MeshBasicMaterial({ color: 0xffd75e, depthTest: false }));
	dot.position.copy(hit.point);
	dot.renderOrder = 1;
	markers.add(dot);
	if (state.points.length === 2) {
		const [a, b] = state.points;
		markers.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints([a, b]),
			new THREE.LineBasicMaterial({ color: 0xffd75e, depthTest: false })));
		state.measurement_mm = a.distanceTo(b) * 1000; // glTF metres → mm
		$('distance').textContent = state.measurement_mm.toFixed(2) + ' mm';
	} else {
		state.measurement_mm = null;
		$('distance').textContent = 'click the second point';
	}
	draw();
});

// For tests and scripts: where a point of the mesh (mm) lands on the canvas, in CSS pixels.
state.project = (x, y, z) => {
	const v = new THREE.Vector3(x / 1000, y / 1000, z / 1000).project(camera);
	const rect = canvas.getBoundingClientRect();
	return [rect.left + (v.x + 1) / 2 * rect.width, rect.top + (1 - v.y) / 2 * rect.height];
};
state.setUi = (on) => { $('toolbar').style.display = on ? '' : 'none'; draw(); };
