"""Model files: the models the package knows and finding them (files), fetching and installing
them (fetch), exporting them (export), and the int8 copy of the detector (quantize)."""
