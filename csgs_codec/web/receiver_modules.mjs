/**
 * Every module of the JavaScript receiver (../js/), imported here for one reason: a worker
 * that imports this module first makes the browser request them all at once, instead of one
 * import level at a time (seven levels deep). Nothing is used from it. tests/web checks that
 * the list names every module the workers reach.
 */

import '../js/anchor_attributes.mjs';
import '../js/anchor_bake.mjs';
import '../js/anchor_payloads.mjs';
import '../js/anchor_scene.mjs';
import '../js/base_layer.mjs';
import '../js/bytes.mjs';
import '../js/categorical.mjs';
import '../js/chunks.mjs';
import '../js/color_layer.mjs';
import '../js/color_prior.mjs';
import '../js/container.mjs';
import '../js/crc32.mjs';
import '../js/decode_plan.mjs';
import '../js/decode_runner.mjs';
import '../js/decode_tasks.mjs';
import '../js/dense_net.mjs';
import '../js/errors.mjs';
import '../js/far_points.mjs';
import '../js/float_stream.mjs';
import '../js/geometry.mjs';
import '../js/histogram.mjs';
import '../js/intnet.mjs';
import '../js/lane_client.mjs';
import '../js/lane_server.mjs';
import '../js/range_decoder.mjs';
import '../js/residual.mjs';
import '../js/scene.mjs';
import '../js/semantic_layer.mjs';
import '../js/tables.mjs';
import '../js/tile_frames.mjs';
import '../js/tile_index.mjs';
import '../js/varints.mjs';
import '../js/view_record.mjs';
import '../js/wasm_assembler.mjs';
import '../js/wasm_intnet.mjs';
import '../js/wasm_range.mjs';
