"""The papers' examples (M8); importing this package registers them."""

from . import gpebo_not_uco as gpebo_not_uco
from . import kkl_pebo_academic as kkl_pebo_academic
