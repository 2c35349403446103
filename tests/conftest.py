import pytest

import gdfe


@pytest.fixture
def table1():
    """Path of the paper's Table 1 shipped with the package."""
    return gdfe.TABLE1
