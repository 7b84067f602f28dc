"""lensmount: lens prescription -> parametric mount CAD -> bidirectional stray-light simulation."""

__version__ = "0.1.0"
