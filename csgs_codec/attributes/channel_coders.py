"""The float stream's channel coders (FORMAT §12.8): the channel record's ``coding`` byte, and
one class per table source that costs, lays out and reads a channel's residuals.

A coded channel's record is: ``coding``, ``mean``, ``step_index``, the scored-step table (when
``coding`` says so), the table source's own fields, the prediction (when ``coding`` says so),
then the residual stream. :mod:`csgs_codec.attributes.float_stream` plans streams and walks the
records; the classes here hold what differs between table sources, so adding one is adding a
class, not a branch in three places.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.entropy.histogram import decode_histogram, encode_histogram, histogram_cost
from csgs_codec.entropy.residual import decode_symbols, encode_symbols
from csgs_codec.entropy.table_choice import table_costs
from csgs_codec.entropy.tables import gaussian_family
from csgs_codec.errors import FormatError
from csgs_codec.format.primitives import ByteReader, ByteWriter

#: Table sources (bits 0-1 of ``coding``).
TABLE_CONSTANT = 0
TABLE_FROZEN = 1
TABLE_HISTOGRAM = 2
TABLE_PRIOR = 3
TABLE_MASK = 0x03
#: ``coding`` flags: the channel is predicted from the channels before it; its steps follow
#: scored classes of decoded attributes.
PREDICTED_FLAG = 0x10
SCORED_FLAG = 0x20
#: Bits a valid ``coding`` byte leaves clear (bits 2-3 and 6-7).
RESERVED_BITS = 0xFF & ~(TABLE_MASK | PREDICTED_FLAG | SCORED_FLAG)
TABLE_NAMES = {TABLE_CONSTANT: "constant", TABLE_FROZEN: "frozen", TABLE_HISTOGRAM: "histogram",
               TABLE_PRIOR: "hyperprior"}


@dataclass(frozen=True)
class ChannelPrior:
    """Per-Gaussian entropy parameters of one channel from the color hyperprior.

    Attributes:
        mean: (N,) int64 rounded mean of the base residual, in steps (may be a strided view).
        scale: (N,) int64 scale-table indices in [0, 63] (may be a strided view).
    """

    mean: np.ndarray
    scale: np.ndarray


@dataclass(frozen=True)
class Coding:
    """A channel record's ``coding`` byte: its table source (``TABLE_*``), whether it is
    predicted from the channels before it, and whether its steps follow scored classes."""

    table: int
    predicted: bool = False
    scored: bool = False

    @property
    def byte(self) -> int:
        """The byte as written."""
        return (self.table | (PREDICTED_FLAG if self.predicted else 0)
                | (SCORED_FLAG if self.scored else 0))

    @property
    def name(self) -> str:
        """Its table source's name, with "+predicted" / "+scored" where set."""
        return (TABLE_NAMES[self.table] + ("+predicted" if self.predicted else "")
                + ("+scored" if self.scored else ""))

    @classmethod
    def read(cls, r: ByteReader, channel: int) -> Coding:
        """Read and check channel ``channel``'s ``coding`` byte.

        Raises:
            FormatError: reserved bits set, a constant channel with a flag, or scored steps
                with a table source other than frozen tables, at the byte's offset.
        """
        at = r.offset
        byte = r.fixed("u8", "coding")
        coding = cls(byte & TABLE_MASK, bool(byte & PREDICTED_FLAG), bool(byte & SCORED_FLAG))
        why = None
        if byte & RESERVED_BITS:
            why = f"coding 0x{byte:02x} sets reserved bits"
        elif coding.table == TABLE_CONSTANT and (coding.predicted or coding.scored):
            why = "a constant channel is neither predicted nor scored"
        elif coding.scored and coding.table != TABLE_FROZEN:
            why = f"scored steps with {TABLE_NAMES[coding.table]} tables (frozen only)"
        if why is not None:
            raise FormatError(f"channel {channel}: {why}", chunk=r.chunk, offset=at)
        return coding


@dataclass(frozen=True)
class ChannelContext:
    """What a coder knows of the stream around one channel.

    Attributes:
        count: N, values in the channel.
        classes: (N,) int64 step class of every Gaussian, or None for one class.
        class_count: K, classes in the channel's step table (1 without scored steps).
        prior: the color hyperprior's parameters of the channel, or None.
    """

    count: int
    classes: np.ndarray | None = None
    class_count: int = 1
    prior: ChannelPrior | None = None


class FrozenTableCoder:
    """Table source 1: residuals coded with frozen Gaussian tables (FORMAT §16.2.1), one
    ``scale_index`` per step class; its fields are those scale indices."""

    table = TABLE_FROZEN

    def cost(self, residuals: np.ndarray, members: list[np.ndarray] | None
             ) -> tuple[float, np.ndarray]:
        """(estimated bits, (K,) int64 best table per class) of ``residuals`` (N,);
        ``members`` are the rows of each class, None for one class."""
        if members is None:
            costs = table_costs(residuals)
            best = int(np.argmin(costs))
            return float(costs[best]), np.array([best], np.int64)
        tables = np.zeros(len(members), np.int64)
        bits = 0.0
        for c, rows in enumerate(members):
            if rows.size:
                costs = table_costs(residuals[rows])
                tables[c] = int(np.argmin(costs))
                bits += float(costs[tables[c]])
        return bits + 8 * len(members), tables

    def write_fields(self, out: ByteWriter, fields: np.ndarray) -> None:
        """Append the scale index of each class."""
        for table in fields:
            out.fixed("u8", int(table))

    def read_fields(self, r: ByteReader, channel: int, context: ChannelContext) -> np.ndarray:
        """(K,) int64 scale indices of the channel's classes.

        Raises:
            FormatError: a scale index outside the table family.
        """
        tables = np.array([r.fixed("u8", "scale_index") for _ in range(context.class_count)],
                          np.int64)
        if tables.max() >= gaussian_family().count:
            raise r.error(f"channel {channel}: scale index {int(tables.max())} out of range")
        return tables

    def encode(self, residuals: np.ndarray, fields: np.ndarray, context: ChannelContext
               ) -> bytes:
        """The residual stream of ``residuals`` (N,) with each value's class table."""
        return encode_symbols(residuals, self._per_value(fields, context))

    def decode(self, stream: bytes, fields: np.ndarray, context: ChannelContext, chunk: str,
               offset: int) -> np.ndarray:
        """(N,) int64 residuals of ``stream`` (at absolute byte ``offset``)."""
        return decode_symbols(stream, self._per_value(fields, context), chunk=chunk,
                              base_offset=offset)

    @staticmethod
    def _per_value(fields: np.ndarray, context: ChannelContext) -> np.ndarray:
        if context.classes is None:
            return np.full(context.count, fields[0], np.int64)
        return fields[context.classes]


class HistogramCoder:
    """Table source 2: residuals coded with a frequency table of their own, carried in the
    stream (FORMAT §16.5); no fields."""

    table = TABLE_HISTOGRAM

    def cost(self, residuals: np.ndarray, members=None) -> tuple[float, None]:
        """(estimated bits, no fields) of ``residuals`` (N,)."""
        return histogram_cost(residuals), None

    def write_fields(self, out: ByteWriter, fields) -> None:
        """No fields."""

    def read_fields(self, r: ByteReader, channel: int, context: ChannelContext) -> None:
        """No fields."""
        return None

    def encode(self, residuals: np.ndarray, fields, context: ChannelContext) -> bytes:
        """The histogram stream of ``residuals`` (N,)."""
        return encode_histogram(residuals)

    def decode(self, stream: bytes, fields, context: ChannelContext, chunk: str,
               offset: int) -> np.ndarray:
        """(N,) int64 residuals of ``stream`` (at absolute byte ``offset``)."""
        return decode_histogram(stream, context.count, chunk=chunk, base_offset=offset)


class PriorCoder:
    """Table source 3: residual i coded around the color hyperprior's mean with its
    per-Gaussian table (FORMAT §12.19); no fields. The encoder decides it with the
    hyperprior (:mod:`csgs_codec.decisions.color_prior_choice`), not by :meth:`cost`."""

    table = TABLE_PRIOR

    def write_fields(self, out: ByteWriter, fields) -> None:
        """No fields."""

    def read_fields(self, r: ByteReader, channel: int, context: ChannelContext) -> None:
        """No fields; the channel must be one the hyperprior models.

        Raises:
            FormatError: no hyperprior parameters for the channel.
        """
        if context.prior is None:
            raise r.error(f"channel {channel} uses the color hyperprior, which does not model "
                          "it (no CHYP chunk, or its channel mask leaves it out)")
        return None

    def encode(self, residuals: np.ndarray, fields, context: ChannelContext) -> bytes:
        """The residual stream of ``residuals`` (N,) minus the prior's means."""
        return encode_symbols(residuals - context.prior.mean, context.prior.scale)

    def decode(self, stream: bytes, fields, context: ChannelContext, chunk: str,
               offset: int) -> np.ndarray:
        """(N,) int64 residuals of ``stream`` (at absolute byte ``offset``), the prior's
        means added back."""
        return decode_symbols(stream, context.prior.scale, chunk=chunk,
                              base_offset=offset) + context.prior.mean


#: Table source -> its coder (a constant channel has none: it codes one float32).
CODERS = {TABLE_FROZEN: FrozenTableCoder(), TABLE_HISTOGRAM: HistogramCoder(),
          TABLE_PRIOR: PriorCoder()}
#: The coders an encoder can cost from the residuals alone (the hyperprior is chosen apart).
PLANNED_CODERS = (CODERS[TABLE_FROZEN], CODERS[TABLE_HISTOGRAM])
