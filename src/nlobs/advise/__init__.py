"""Advise: which observer fits a model? The observability verdict, every registered kind tried with an
automatic tuning (applies / why not / what to supply), and a ranking measured on a run."""

from ._advice import Advice as Advice
from ._advice import Candidate as Candidate
from ._advice import Score as Score
from ._advise import advise as advise
from ._tune import tune as tune
