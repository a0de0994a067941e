"""The papers' examples (SPEC M8), each a registered function returning an ExampleResult; and practitioners' models
(:data:`PRACTICE`: a battery with an OCV table, a discrete-time building, a multi-rate vehicle) for the docs' gallery."""

from . import pendulum as pendulum
from . import toy_augmented as toy_augmented
from ._base import ALIASES as ALIASES
from ._base import EXAMPLES as EXAMPLES
from ._base import PRACTICE as PRACTICE
from ._base import find_example as find_example
from ._base import Claim as Claim
from ._base import ExampleResult as ExampleResult
from ._base import register as register
from ._base import rows_from_run as rows_from_run
from . import banks as banks  # noqa: E402
from . import van_der_pol_unknown as van_der_pol_unknown  # noqa: E402
from . import pendulum_unknown_b as pendulum_unknown_b  # noqa: E402
from . import range_localisation as range_localisation  # noqa: E402
from . import gpebo_not_uco as gpebo_not_uco  # noqa: E402  (000, M8 #7)
from . import kkl_pebo_academic as kkl_pebo_academic  # noqa: E402  (004 §V-A, M8 #8)
from . import cuk_converter as cuk_converter  # noqa: E402  (004 §V-C, M8 #9)
from . import battery_ocv as battery_ocv  # noqa: E402  (practice)
from . import building_map as building_map  # noqa: E402  (practice)
from . import vehicle_multirate as vehicle_multirate  # noqa: E402  (practice)
