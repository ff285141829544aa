// The AOBAKE_lightmap extension object as both engine importers read it
// (the packages aobake-three for three.js and aobake-babylon for
// Babylon.js): the name, and why an object cannot be used. No engine
// import, so either importer can use it.
//
// In: a primitive's extension object and the glTF JSON. Out: null, or one
// line saying what is wrong (the importers report it, never throw).

export const EXTENSION = 'AOBAKE_lightmap';

/** Why an extension object cannot be used, or null. */
export function extensionProblem(ext, json) {
  if (typeof ext !== 'object' || ext === null) return 'is not an object';
  const textures = json.textures ?? [];
  const texture = (ref, what) => {
    if (typeof ref !== 'object' || ref === null || !Number.isInteger(ref.index)) {
      return `${what} has no texture index`;
    }
    if (ref.index < 0 || ref.index >= textures.length) {
      return `${what} names textures[${ref.index}], which does not exist`;
    }
    return null;
  };
  if (!Number.isInteger(ext.texCoord) || ext.texCoord < 0) return 'texCoord is not a set index';
  const occ = texture(ext.occlusion, 'occlusion');
  if (occ) return occ;
  if (!Array.isArray(ext.sh) || ext.sh.length !== 3) return 'sh must list 3 textures';
  for (let i = 0; i < 3; i++) {
    const p = texture(ext.sh[i], `sh[${i}]`);
    if (p) return p;
  }
  const numbers = (key, count) => {
    const v = ext[key];
    if (!Array.isArray(v) || v.length !== count) {
      return `${key} must hold ${count} numbers (has ${Array.isArray(v) ? v.length : 'none'})`;
    }
    if (!v.every((x) => typeof x === 'number' && Number.isFinite(x))) {
      return `${key} holds a value that is not a finite number`;
    }
    return null;
  };
  for (const key of ['shScale', 'shOffset']) {
    const p = numbers(key, 9);
    if (p) return p;
  }
  if (ext.visibility !== undefined) {
    const v = ext.visibility;
    if (!Array.isArray(v) || (v.length !== 4 && v.length !== 3)) {
      return 'visibility must list 4 (order 3) or 3 (order 2) textures';
    }
    for (let i = 0; i < v.length; i++) {
      const p = texture(v[i], `visibility[${i}]`);
      if (p) return p;
    }
    const count = v.length === 4 ? 16 : 9;
    for (const key of ['visibilityScale', 'visibilityOffset']) {
      const p = numbers(key, count);
      if (p) return p;
    }
  }
  return null;
}


/** The lookup a file's texels are fitted for (the root extension's
 * `filter`): { filter: 'bilinear' | 'bicubic', problem: null | one line }.
 * Absent: bilinear. A value this reader does not know is read bilinearly,
 * with a problem line saying so. */
export function filterOf(record) {
  const f = record?.filter ?? 'bilinear';
  if (f === 'bilinear' || f === 'bicubic') return { filter: f, problem: null };
  return {
    filter: 'bilinear',
    problem: `${EXTENSION} filter ${JSON.stringify(f)} is not one this reader knows (bilinear, bicubic): read bilinearly`,
  };
}
