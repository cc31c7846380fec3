"""Unit tests of occgeo.mapfile, the port of mapping/mapfile (no server needed)."""

import os
import tempfile
import unittest

from occgeo import CertaintyWindow
from occgeo.mapfile import CertaintyGreyLevels, format_number, image_from_certainty, write_map


class FormatNumberTest(unittest.TestCase):
    def test_shortest_round_trip_like_to_chars(self):
        cases = {0.05: "0.05", -10.0: "-10", 0.0: "0", 100000.0: "1e+05", 12345.0: "12345", 1e-05: "1e-05",
                 0.001: "0.001", -6.4: "-6.4", 0.16666666666666669: "0.16666666666666669", 1e22: "1e+22",
                 1.5e-07: "1.5e-07", 123456789.0: "123456789"}
        for value, text in cases.items():
            with self.subTest(value=value):
                self.assertEqual(format_number(value), text)
                self.assertEqual(float(text), value)


class GreyLevelsTest(unittest.TestCase):
    def test_default_parameters(self):
        levels = CertaintyGreyLevels(15, 3)
        self.assertEqual(levels.grey_of_certainty,
                         [254, 237, 220, 203, 186, 169, 152, 135, 119, 102, 85, 68, 51, 34, 17, 0])
        self.assertEqual(levels.grey_of(255), 205)
        self.assertEqual(levels.occupied_thresh, 0.2)

    def test_levels_are_distinct_and_thresholds_separate_them(self):
        for maximum in range(1, 16):
            for threshold in range(1, maximum + 1):
                levels = CertaintyGreyLevels(maximum, threshold)
                greys = levels.grey_of_certainty
                self.assertEqual(len(set(greys + [205])), maximum + 2)
                for c, grey in enumerate(greys):
                    p = (255 - grey) / 255.0
                    self.assertEqual(p > levels.occupied_thresh, c >= threshold, (maximum, threshold, c))
                    self.assertEqual(p < levels.free_thresh, c < threshold, (maximum, threshold, c))
                p = 50 / 255.0
                self.assertTrue(levels.free_thresh <= p <= levels.occupied_thresh)

    def test_bad_parameters(self):
        with self.assertRaises(ValueError):
            CertaintyGreyLevels(15, 0)
        with self.assertRaises(ValueError):
            CertaintyGreyLevels(16, 3)


class WriteMapTest(unittest.TestCase):
    def test_image_rows_are_flipped_and_files_written(self):
        window = CertaintyWindow("w", 0.1, -2, 3, 3, 2, bytes([0, 15, 255, 3, 2, 20]), 3, 15, 7)
        image = image_from_certainty(window)
        # Image row 0 is the window's top row (iy = 4); values above max are clamped.
        self.assertEqual(image.pixels, bytes([203, 220, 0, 254, 0, 205]))
        with tempfile.TemporaryDirectory() as tmp:
            pgm, yaml = write_map(os.path.join(tmp, "m"), image)
            with open(pgm, "rb") as f:
                self.assertEqual(f.read(), b"P5\n3 2\n255\n" + image.pixels)
            with open(yaml, "rb") as f:
                self.assertEqual(f.read(), b'image: "m.pgm"\nmode: trinary\nresolution: 0.1\n'
                                           b"origin: [-0.2, 0.30000000000000004, 0]\nnegate: 0\n"
                                           b"occupied_thresh: 0.2\nfree_thresh: 0.16666666666666669\n")


if __name__ == "__main__":
    unittest.main()
