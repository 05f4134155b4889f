"""Frame decoders, one sub-package per drive model; `registry` picks one per unit."""
