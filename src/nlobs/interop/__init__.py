"""Interoperability with other tools: python-control (imported only when used).

Nothing inside nlobs imports this package except ``nlobs/__init__.py`` and the CLI.
"""

from .control import from_control as from_control
from .control import to_control as to_control
