"""The simulation engine: sampled controller, exact delayed lookup, RK4 plant, batching."""

import lazy_loader

# The names of __init__.pyi, each imported from its module when first used: importing one
# module of the package runs this file, which then imports none of the others.
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
