"""Report: numbers and pictures (the demo report)."""

from ._demo import DemoOutcome as DemoOutcome
from ._demo import run_demo as run_demo
