"""Geometry export of simulated shots for other tools: `fraytool export SCENE --usd OUT.usd` (usd).

It reads frame records like the renderer, and reuses the renderer's yarn geometry (fraytool.render:
the centre lines its tubes follow and the fade of broken ends), so what a DCC shows is what fraytool
draws. The USD library (pxr, from usd-core) is an optional extra: pip install "fraytool[usd]".
"""
