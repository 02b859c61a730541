"""What the encoder decides, none of which the format fixes: the quality presets and their
steps, per-scene step allocation, rate control (target PSNR, lambda), view pruning,
refinement, whether the color hyperprior pays, and which points are coded apart as far
points. Every choice is recorded in the stream it shapes, so the decoders never import this
package (tests/packaging/test_import_graph.py)."""
