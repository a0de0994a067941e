"""Report: numbers and pictures. The demo report, and the building blocks any HTML report of
nlobs is made of (sections, tables, figures, maths, a bibliography), all self-contained."""

from ._demo import DemoOutcome as DemoOutcome
from ._demo import example_section as example_section
from ._demo import run_demo as run_demo
from ._demo import summary_table as summary_table
from ._html import HTML as HTML
from ._html import bibliography as bibliography
from ._html import details as details
from ._html import equations as equations
from ._html import expr as expr
from ._html import figure as figure
from ._html import fmt as fmt
from ._html import maths as maths
from ._html import page as page
from ._html import plain as plain
from ._html import pre as pre
from ._html import prose as prose
from ._html import section as section
from ._html import table as table
from ._model_report import model_report as model_report
from ._model_report import parameter_estimates as parameter_estimates
from ._model_report import write_model_report as write_model_report
from ._sensors import sensors_figure as sensors_figure

__all__ = ["HTML", "DemoOutcome", "run_demo", "example_section", "summary_table", "bibliography", "details", "equations", "expr",
           "figure", "fmt", "maths", "page", "plain", "pre", "prose", "section", "table", "model_report", "parameter_estimates",
           "write_model_report", "sensors_figure"]
