import os

import pytest
from hypothesis import HealthCheck, settings

import gdfe

# Property-based tests (Hypothesis): a few dozen examples per property in the default run,
# deterministic (derandomized: the same examples on every run, no example database), so CI is
# stable; the tests marked slow rerun each property with the "long" profile's many more examples.
settings.register_profile("default", max_examples=25, derandomize=True, database=None, deadline=None,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
settings.register_profile("long", parent=settings.get_profile("default"), max_examples=400)
settings.load_profile(os.environ.get("GDFE_HYPOTHESIS_PROFILE", "default"))


@pytest.fixture
def table1():
    """Path of the paper's Table 1 shipped with the package."""
    return gdfe.TABLE1
