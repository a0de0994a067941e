"""Support: compile a System once to CasADi (f, h, Jacobians), integrate, generate C."""

from ._batch import evaluate_many as evaluate_many
from ._casadi import CASADI as CASADI
from ._casadi import CompiledSystem as CompiledSystem
from ._casadi import compile_system as compile_system
from ._casadi import rows as rows
from ._casadi import to_casadi as to_casadi
from ._codegen import Backend as Backend
from ._codegen import cache_dir as cache_dir
from ._codegen import choose_backend as choose_backend
from ._codegen import compile_c as compile_c
from ._codegen import find_compiler as find_compiler
from ._codegen import resolve_backend as resolve_backend
from ._deferred import clear_deferred as clear_deferred
from ._deferred import defer_error as defer_error
from ._deferred import raise_deferred as raise_deferred
from ._integrate import DEFAULT_CHUNK as DEFAULT_CHUNK
from ._integrate import StepRunner as StepRunner
from ._integrate import rk4_step as rk4_step
from ._integrate import batch_backend as batch_backend
from ._integrate import run_batch as run_batch
from ._integrate import saved_steps as saved_steps
from ._integrate import usable_cores as usable_cores
from ._nlp import compiled_nlpsol as compiled_nlpsol
