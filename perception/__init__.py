"""Perception: the dataset format and loaders, the regressors (AlexNet, VGG-16, GIST), training and evaluation.

Import submodules directly; this package does not import torch on its own, so the dataset format stays
usable by light tools.
"""
