"""The toolbox version (its own module, so that any module can read it without importing the
package's ``__init__``, which imports the runner)."""

__version__ = "0.1.0"
