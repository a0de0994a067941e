"""Report: numbers and pictures (the demo report)."""

from ._demo import DemoOutcome as DemoOutcome
from ._demo import run_demo as run_demo
from ._model_report import model_report as model_report
from ._model_report import parameter_estimates as parameter_estimates
from ._model_report import write_model_report as write_model_report
