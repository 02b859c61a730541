"""How each attribute of a scene becomes integers and back: coding forms (attribute_forms),
the position grid and far points (position_grid, far_positions), the scene's float streams
(streams) and how each of their channels is quantized and coded (float_stream,
channel_coders, derived_steps), the SH bands' colour transform (sh_colour_transform), and the
anchor grid of anchor scenes (anchor_grid). FORMAT §12 specifies what a decoder computes
here; the chunks that carry the results are :mod:`csgs_codec.chunks`'."""
