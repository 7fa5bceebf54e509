// The parts of three.js the exported HTML viewer uses, bundled by build.sh into one classic
// (IIFE) script that sets window.VEBUILD_THREE: a page opened from file:// may not load ES
// modules, so the bundle is made once here and committed as three-bundle.min.js.
export * as THREE from "three";
export { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
export { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
export { PointerLockControls } from "three/examples/jsm/controls/PointerLockControls.js";
export { VRButton } from "three/examples/jsm/webxr/VRButton.js";
