"""Models: what the engineer writes (System, structured forms, model files, input signals)."""

from ._expr import FUNCTIONS as FUNCTIONS
from ._expr import parse_expression as parse_expression
from ._forms import LTI as LTI
from ._forms import OutputInjectionForm as OutputInjectionForm
from ._forms import StateAffine as StateAffine
from ._signals import AbstractSignal as AbstractSignal
from ._signals import Expression as Expression
from ._signals import Function as Function
from ._signals import Sampled as Sampled
from ._signals import as_signal as as_signal
from ._signals import input_signals as input_signals
from ._system import TIME as TIME
from ._tables import MAX_TABLE_POINTS as MAX_TABLE_POINTS
from ._tables import Table as Table
from ._system import System as System
from ._system import symbol as symbol
from ._toml import ModelFile as ModelFile
from ._toml import ObserverConfig as ObserverConfig
from ._toml import SimulationConfig as SimulationConfig
from ._toml import load_model as load_model
from ._toml import loads_model as loads_model
from ._translate import translate as translate
from ._library import LibraryEntry as LibraryEntry
from ._library import bundled_names as bundled_names
from ._library import bundled_path as bundled_path
from ._toml import library as library
