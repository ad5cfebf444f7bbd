#!/usr/bin/env node
// Convert an npm mesh module exporting {positions: [[x,y,z],...], cells: [[a,b,c],...]}
// (e.g. bunny@1.0.1, teapot@1.0.0) into a Wavefront OBJ file. No dependencies.
//
// Usage: node tools/data/npm_mesh_to_obj.js <path/to/package/module.js> [out.obj]
//   Writes to stdout when no output path is given.
//   The header names the package and license read from the package.json next to the module.
//
// Coordinates are written with String(number), i.e. the shortest text that round-trips to
// the exact same double, so no precision is lost (and nothing is rounded). Cells are
// 0-based in the source and written 1-based as OBJ requires.
'use strict';
const fs = require('fs');
const path = require('path');

function fail(msg) {
  process.stderr.write('npm_mesh_to_obj: ' + msg + '\n');
  process.exit(1);
}

const [modArg, outArg] = process.argv.slice(2);
if (!modArg) fail('usage: npm_mesh_to_obj.js <module.js> [out.obj]');
const modPath = path.resolve(modArg);
const pkgPath = path.join(path.dirname(modPath), 'package.json');
const pkg = fs.existsSync(pkgPath) ? JSON.parse(fs.readFileSync(pkgPath, 'utf8')) : {};
const mesh = require(modPath);
const { positions, cells } = mesh;
if (!Array.isArray(positions) || !Array.isArray(cells)) fail('module lacks positions/cells arrays');

const lines = [];
lines.push('# ' + (pkg.name || '?') + '@' + (pkg.version || '?') + ' (npm, ' +
  path.basename(modPath) + '), license: ' + (pkg.license || 'unknown') +
  '; converted by tools/data/npm_mesh_to_obj.js');
positions.forEach((p, i) => {
  if (p.length !== 3 || !p.every(Number.isFinite)) fail('bad position ' + i);
  lines.push('v ' + p.map(String).join(' '));
});
cells.forEach((c, i) => {
  if (c.length !== 3) fail('cell ' + i + ' is not a triangle');
  for (const k of c) {
    if (!Number.isInteger(k) || k < 0 || k >= positions.length) fail('cell ' + i + ' index out of range: ' + k);
  }
  lines.push('f ' + c.map((k) => String(k + 1)).join(' '));
});
const text = lines.join('\n') + '\n';
if (outArg) fs.writeFileSync(outArg, text);
else process.stdout.write(text);
process.stderr.write((pkg.name || modArg) + ': ' + positions.length + ' vertices, ' + cells.length + ' triangles\n');
