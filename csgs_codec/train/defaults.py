"""Default training settings as plain constants, importable without torch.

The CLI builds its option help from these at start-up; importing the training modules there
would import torch and slow every ``csgs`` command (``info``, ``decode``) by seconds.
"""

#: CSGaussian's lambda_rate presets (low, mid, high rate weight).
RATE_WEIGHT_PRESETS = (0.004, 0.01, 0.02)
#: Stage-1 steps, encoder quality, anchor feature width and offsets per anchor.
ITERATIONS = 2000
QUALITY = 5
FEAT_DIM = 32
N_OFFSETS = 10
#: Anchors stage 1 starts from, and the most growth may reach.
INITIAL_ANCHORS = 2000
MAX_ANCHORS = 20000
#: torch CPU threads while training (one: the result does not depend on the core count).
THREADS = 1
#: Stage-2 steps (stage 3 runs two thirds as many).
SEMANTIC_ITERATIONS = 150
#: Stage 3's lambda_feature_rate: estimated bits per anchor of s against the stage-2 loss.
#: Measured with benchmarks/train.py's scene (margin 4): 0.1 -> 1.0 makes the semantic
#: chunk 10-16% smaller with click mIoU unchanged.
FEATURE_RATE_WEIGHT = 1.0
#: Margin of the inter-mask contrastive loss, in quantization steps of s. It sets how far
#: apart the masks' mean features sit, so the semantic layer's size: on benchmarks/train.py's
#: scene margin 6 -> 4 shrinks that layer by 27-41% with click mIoU still 0.9995-1.0 per
#: anchor (0.96 in 2D); margin 3 was measured to lose mIoU (0.86-0.95, losses.py).
CONTRASTIVE_MARGIN = 4.0
