// What `aobake view`'s Babylon.js page (viewer/babylon-viewer.js) imports:
// the Babylon.js pieces it uses and the package aobake-babylon, bundled into
// one module by build-viewer.mjs (viewer/vendor/babylon/aobake-babylon.js.gz,
// served gzip-encoded and built into the binary).

import '@babylonjs/core/Materials/PBR/pbrMaterial.js';
import '@babylonjs/core/Loading/loadingScreen.js';
import '@babylonjs/loaders/glTF/2.0/index.js';

export { Engine } from '@babylonjs/core/Engines/engine.js';
export { Scene } from '@babylonjs/core/scene.js';
export { ArcRotateCamera } from '@babylonjs/core/Cameras/arcRotateCamera.js';
export { Vector3 } from '@babylonjs/core/Maths/math.vector.js';
export { Color4 } from '@babylonjs/core/Maths/math.color.js';
export { RawCubeTexture } from '@babylonjs/core/Materials/Textures/rawCubeTexture.js';
export { CubeMapToSphericalPolynomialTools } from '@babylonjs/core/Misc/HighDynamicRange/cubemapToSphericalPolynomial.js';
export { SceneLoader } from '@babylonjs/core/Loading/sceneLoader.js';
export { Constants } from '@babylonjs/core/Engines/constants.js';
export { HDRFiltering } from '@babylonjs/core/Materials/Textures/Filtering/hdrFiltering.js';
export { ToHalfFloat } from '@babylonjs/core/Misc/halfFloat.js';
export { AobakeLightmaps, registerAobakeLightmap, toBakeRows } from 'aobake-babylon';
