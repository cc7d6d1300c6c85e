"""Golden-image regression tests of a user's own scenes (docs/golden.md).

`fraytool golden update` stores, per chosen frame of a scene, a 16-bit PNG, the yarn geometry and one
metadata file; `fraytool golden check` renders the same frames again and compares them, images by
idiff-style thresholds and SSIM, geometry by yarn-point distance and the torn-spring count, and writes
reports a browser and a CI can read. `fraytool.testing` wraps the same for a pytest suite.

- capture.py: simulate and draw the chosen frames (16-bit sRGB images, yarn points, torn springs);
- compare.py: the figures and the pass / warn / fail verdict of one frame;
- store.py: the golden folder (files, metadata);
- report.py: diff images, report.html, summary.json, JUnit XML.
"""
