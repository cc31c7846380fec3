"""ROS map_server maps (PGM + YAML) from HIMM certainty windows.

A Python port of mapping/mapfile/src/certainty_image.cc (``CertaintyGreyLevels``,
``image_from_certainty``) and the writer of mapping/mapfile/src/map_file.cc (``write_map``): the
same grey level for every certainty, the same thresholds, and the same bytes in both files, so a
map exported from Python equals ``occgeo map export --format pgm`` byte for byte.
"""

import decimal
import math
import os

#: Cell value of a HIMM cell never observed (GridReply.cells).
UNOBSERVED_CERTAINTY = 255
#: Grey level of unobserved cells: map_server reads it as unknown.
UNOBSERVED_GREY = 205


def _occupancy_probability(grey):
    return (255.0 - grey) / 255.0


def _lround(value):
    """C's lround for the non-negative values used here (half away from zero)."""
    return int(math.floor(value + 0.5))


class CertaintyGreyLevels:
    """The lossless mapping between HIMM certainties (0..max_certainty, or 255 unobserved) and PGM
    grey levels, with the map_server thresholds that read exactly the certainties >=
    occupied_threshold as occupied (see certainty_image.h)."""

    def __init__(self, max_certainty, occupied_threshold):
        if not 1 <= occupied_threshold <= max_certainty <= 15:
            raise ValueError(
                "certainty window: occupied_threshold %d and max_certainty %d must satisfy "
                "1 <= threshold <= max <= 15" % (occupied_threshold, max_certainty)
            )
        m = int(max_certainty)
        t = int(occupied_threshold)
        uniform_step = 254.0 / m
        free_step = min(uniform_step, (254.0 - 206.0) / (t - 1)) if t > 1 else uniform_step
        occupied_step = min(uniform_step, 204.0 / (m - t)) if m > t else uniform_step
        self.max_certainty = m
        self.occupied_threshold = t
        self.grey_of_certainty = []
        for c in range(m + 1):
            grey = 254.0 - c * free_step if c < t else (m - c) * occupied_step
            self.grey_of_certainty.append(_lround(grey) & 0xFF)
        p_unobserved = _occupancy_probability(UNOBSERVED_GREY)
        self.free_thresh = 0.5 * (_occupancy_probability(self.grey_of_certainty[t - 1]) + p_unobserved)
        self.occupied_thresh = 0.5 * (p_unobserved + _occupancy_probability(self.grey_of_certainty[t]))
        # Lookup table from cell value to grey level (values above max are clamped to max).
        table = bytearray(256)
        for value in range(256):
            if value == UNOBSERVED_CERTAINTY:
                table[value] = UNOBSERVED_GREY
            else:
                table[value] = self.grey_of_certainty[min(value, m)]
        self.table = bytes(table)

    def grey_of(self, value):
        """Grey level (0..255) of a cell value (a certainty, or 255 for unobserved)."""
        return self.table[value]


class OccupancyImage:
    """A map_server image: ``pixels`` row-major, row 0 at the top (largest y); ``origin_x``,
    ``origin_y`` (metres, world frame) the lower-left corner of the bottom-left pixel."""

    def __init__(self, width, height, resolution, origin_x, origin_y, occupied_thresh, free_thresh, pixels):
        self.width = width
        self.height = height
        self.resolution = resolution
        self.origin_x = origin_x
        self.origin_y = origin_y
        self.occupied_thresh = occupied_thresh
        self.free_thresh = free_thresh
        self.negate = False
        self.pixels = pixels


def image_from_certainty(window):
    """The map_server image of a :class:`occgeo.CertaintyWindow` (as certainty_image.cc does)."""
    levels = CertaintyGreyLevels(window.max_certainty, window.occupied_threshold)
    if len(window.cells) != window.width * window.height:
        raise ValueError(
            "certainty window: %d cells for %d x %d" % (len(window.cells), window.width, window.height)
        )
    cells = bytes(window.cells)
    translated = cells.translate(levels.table)
    w = window.width
    pixels = bytearray()
    for row in range(window.height):
        window_row = window.height - 1 - row  # image row 0 is the top, window row 0 the bottom
        pixels += translated[window_row * w:(window_row + 1) * w]
    return OccupancyImage(
        width=window.width,
        height=window.height,
        resolution=window.cell_size_m,
        origin_x=window.min_ix * window.cell_size_m,
        origin_y=window.min_iy * window.cell_size_m,
        occupied_thresh=levels.occupied_thresh,
        free_thresh=levels.free_thresh,
        pixels=bytes(pixels),
    )


def format_number(value):
    """``value`` in its shortest form that reads back exactly, as C++'s ``std::to_chars(double)``:
    the shorter of fixed and scientific notation (fixed on a tie), e.g. 0.05, -10, 1e+05."""
    value = float(value)
    if math.isnan(value) or math.isinf(value):
        return "?"
    if value == 0.0:
        return "-0" if math.copysign(1.0, value) < 0 else "0"
    sign = "-" if value < 0 else ""
    digits_tuple = decimal.Decimal(repr(abs(value))).normalize(decimal.Context(prec=40)).as_tuple()
    digits = "".join(str(d) for d in digits_tuple.digits)
    exponent = digits_tuple.exponent  # value = int(digits) * 10**exponent
    n = len(digits)
    scientific_exponent = exponent + n - 1
    mantissa = digits[0] + ("." + digits[1:] if n > 1 else "")
    scientific = "%se%s%02d" % (mantissa, "-" if scientific_exponent < 0 else "+", abs(scientific_exponent))
    if exponent >= 0:
        fixed = digits + "0" * exponent
    else:
        before_point = n + exponent
        if before_point > 0:
            fixed = digits[:before_point] + "." + digits[before_point:]
        else:
            fixed = "0." + "0" * (-before_point) + digits
    return sign + (fixed if len(fixed) <= len(scientific) else scientific)


def _quoted(name_bytes):
    """YAML double-quoted form of a file name (bytes), as map_file.cc writes it."""
    out = bytearray(b'"')
    for c in name_bytes:
        if c in (0x22, 0x5C):
            out += b"\\" + bytes([c])
        elif c < 0x20:
            out += b"\\x" + b"0123456789abcdef"[c >> 4:(c >> 4) + 1] + b"0123456789abcdef"[c & 0xF:(c & 0xF) + 1]
        else:
            out.append(c)
    return bytes(out + b'"')


def write_map(prefix, image):
    """Writes ``PREFIX.pgm`` (binary P5, 8-bit) and ``PREFIX.yaml`` (map_server keys) for an
    :class:`OccupancyImage`; returns the two paths."""
    if len(image.pixels) != image.width * image.height:
        raise ValueError("%s: image has %d pixels, width * height is %d"
                         % (prefix, len(image.pixels), image.width * image.height))
    if not (math.isfinite(image.resolution) and image.resolution > 0.0):
        raise ValueError("%s: resolution must be a finite number > 0" % prefix)
    prefix = os.fspath(prefix)
    pgm_path = prefix + ".pgm"
    yaml_path = prefix + ".yaml"
    with open(pgm_path, "wb") as out:
        out.write(b"P5\n%d %d\n255\n" % (image.width, image.height))
        out.write(image.pixels)
    yaml = (
        b"image: " + _quoted(os.fsencode(os.path.basename(pgm_path))) + b"\n"
        + b"mode: trinary\n"
        + b"resolution: " + format_number(image.resolution).encode() + b"\n"
        + b"origin: [" + format_number(image.origin_x).encode() + b", "
        + format_number(image.origin_y).encode() + b", 0]\n"
        + b"negate: " + (b"1" if image.negate else b"0") + b"\n"
        + b"occupied_thresh: " + format_number(image.occupied_thresh).encode() + b"\n"
        + b"free_thresh: " + format_number(image.free_thresh).encode() + b"\n"
    )
    with open(yaml_path, "wb") as out:
        out.write(yaml)
    return pgm_path, yaml_path
