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


@pytest.fixture(scope="session")
def coarse_study(tmp_path_factory):
    """``coarse_study(name) -> (result, folder)``: a registered study run once per test session at its
    coarsest resolution (the study-wide test and a study's own tests share the run)."""
    import studies
    from studies._common import RESOLUTIONS

    runs = {}

    def run(name):
        if name not in runs:
            out = tmp_path_factory.mktemp(f"study-{name}")
            runs[name] = (studies.load(name).run(RESOLUTIONS[0], out), out)
        return runs[name]

    return run
