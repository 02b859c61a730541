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
FEATURE_RATE_WEIGHT = 0.1
#: Margin of the inter-mask contrastive loss, in quantization steps of s.
CONTRASTIVE_MARGIN = 6.0
