/**
 * Runs level_view.mjs's cut choice on a synthetic tile tree (JSON on stdin: {tiles, camera,
 * sizes: [[number, size], ...], decoded: [numbers], budget, pixels}) and prints {cut,
 * drawn, missing} as JSON (tile numbers, increasing).
 */

import { chooseCut, drawnTiles } from '../../csgs_codec/web/level_view.mjs';

let input = '';
process.stdin.on('data', (chunk) => { input += chunk; });
process.stdin.on('end', () => {
  const { tiles, camera, sizes, decoded, budget, pixels } = JSON.parse(input);
  const children = tiles.map(() => []);
  tiles.forEach((t, i) => { if (t.parent !== null) children[t.parent].push(i); });
  const cut = chooseCut(tiles, children, camera, new Map(sizes), { budget, pixels });
  const { drawn, missing } = drawnTiles(tiles, children, cut, new Set(decoded));
  const sorted = (s) => [...s].sort((a, b) => a - b);
  process.stdout.write(JSON.stringify({ cut: sorted(cut), drawn: sorted(drawn), missing: sorted(missing) }));
});
