"""Octree node state and the contexts of the geometry coder (shared by encoder and decoder).

A node at level ``d`` is the Morton prefix of its points (3 bits per level). Child ``k`` of a
node has x offset ``k & 1``, y offset ``(k >> 1) & 1`` and z offset ``(k >> 2) & 1``, so the
children's codes are ``8 * parent + k``. Everything here depends only on levels already
decoded, which is what lets the decoder code a whole level with a few grouped calls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Number of set bits of every byte.
POPCOUNT = np.array([bin(v).count("1") for v in range(256)], np.uint8)

#: Occupancy contexts: 16 for (occupied face siblings 0..3, parent popcount 1, 2, 3, >= 4),
#: then one for the root.
OCCUPANCY_CONTEXTS = 17
ROOT_OCCUPANCY_CONTEXT = 16


def _frames() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (parent occupancy P, child index k): the context and the maps into/out of the frame.

    The node's frame mirrors it to child 0 of its parent (child j -> j XOR k), then reorders
    the axes so that the axes with an occupied face sibling come first, in x, y, z order, then
    the others in x, y, z order. Returns OCC_CONTEXT (256, 8), TO_FRAME and FROM_FRAME
    (256, 8, 256): occupancy byte in the world frame <-> in the node's frame.
    """
    context = np.zeros((256, 8), np.uint8)
    child_map = np.zeros((256, 8, 8), np.uint16)
    for occ in range(256):
        for k in range(8):
            sib = [(occ >> (k ^ (1 << axis))) & 1 for axis in range(3)]
            order = [axis for axis in range(3) if sib[axis]] + [
                axis for axis in range(3) if not sib[axis]]
            context[occ, k] = 4 * sum(sib) + min(max(int(POPCOUNT[occ]), 1), 4) - 1
            for j in range(8):
                m = j ^ k
                child_map[occ, k, j] = sum(((m >> order[i]) & 1) << i for i in range(3))
    byte_bits = (np.arange(256, dtype=np.uint16)[:, None] >> np.arange(8, dtype=np.uint16)) & 1
    to_frame = (byte_bits[None, None] << child_map[:, :, None, :]).sum(axis=-1).astype(np.uint8)
    from_frame = np.argsort(to_frame, axis=-1).astype(np.uint8)
    return context, to_frame, from_frame


OCC_CONTEXT, TO_FRAME, FROM_FRAME = _frames()

#: Direct-mode flag contexts: root, then by the popcount of the grandparent (<= 1, 2, >= 3).
FLAG_CONTEXTS = 4


@dataclass
class Nodes:
    """The occupied nodes of one octree level still coded by occupancy, in Morton order.

    Attributes:
        codes: (M,) uint64 Morton prefixes at this level.
        parent_occupancy: (M,) uint8 occupancy byte of each node's parent (0 at the root).
        child_index: (M,) uint8 position ``k`` of the node inside its parent.
        grandparent_popcount: (M,) uint8 popcount of the parent's parent occupancy (0 if none).
    """

    codes: np.ndarray
    parent_occupancy: np.ndarray
    child_index: np.ndarray
    grandparent_popcount: np.ndarray

    @staticmethod
    def root() -> Nodes:
        """The single node of level 0."""
        zero = np.zeros(1, np.uint8)
        return Nodes(np.zeros(1, np.uint64), zero, zero.copy(), zero.copy())

    def __len__(self) -> int:
        return int(self.codes.shape[0])

    def subset(self, keep: np.ndarray) -> Nodes:
        """The nodes selected by a (M,) boolean mask."""
        return Nodes(self.codes[keep], self.parent_occupancy[keep], self.child_index[keep],
                     self.grandparent_popcount[keep])

    def children(self, occupancy: np.ndarray) -> Nodes:
        """Nodes of the next level given each node's (M,) uint8 occupancy byte (1..255)."""
        # One bool per child slot, node-major: slot 8 * row + k. (nonzero is much faster on
        # a bool view than on uint8.)
        slots = np.flatnonzero(np.unpackbits(occupancy, bitorder="little").view(bool))
        rows = slots >> 3
        ks = (slots & 7).astype(np.uint8)
        return Nodes(
            (self.codes[rows] << np.uint64(3)) | ks.astype(np.uint64),
            occupancy[rows],
            ks,
            POPCOUNT[self.parent_occupancy[rows]],
        )


def direct_eligible(nodes: Nodes, level: int) -> np.ndarray:
    """(M,) bool: nodes that carry a direct-mode flag (the root, and every only child)."""
    if level == 0:
        return np.ones(len(nodes), bool)
    return POPCOUNT[nodes.parent_occupancy] == 1


def flag_contexts(nodes: Nodes, level: int) -> np.ndarray:
    """(M,) uint8 direct-flag context of each node (meaningful where eligible)."""
    if level == 0:
        return np.zeros(len(nodes), np.uint8)
    return np.clip(nodes.grandparent_popcount, 1, 3).astype(np.uint8)


def occupancy_contexts(nodes: Nodes, level: int) -> np.ndarray:
    """(M,) uint8 occupancy context of each node."""
    if level == 0:
        return np.full(len(nodes), ROOT_OCCUPANCY_CONTEXT, np.uint8)
    return OCC_CONTEXT[nodes.parent_occupancy, nodes.child_index]


def occupancy_to_symbols(nodes: Nodes, occupancy: np.ndarray) -> np.ndarray:
    """(M,) occupancy bytes 1..255 -> coded symbols 0..254 (mirrored into the node's frame)."""
    return TO_FRAME[nodes.parent_occupancy, nodes.child_index, occupancy].astype(np.int64) - 1


def symbols_to_occupancy(nodes: Nodes, symbols: np.ndarray) -> np.ndarray:
    """Inverse of :func:`occupancy_to_symbols`: (M,) symbols 0..254 -> occupancy bytes."""
    frame = (nodes.parent_occupancy.astype(np.int64) << 11) | (
        nodes.child_index.astype(np.int64) << 8)
    return FROM_FRAME.reshape(-1)[frame | (symbols + 1)]
