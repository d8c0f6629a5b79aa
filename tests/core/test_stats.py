"""nlos_cl.core.stats.chi2_quantile against SciPy (the reference it replaces to keep SciPy out
of a one-shot locate): 1e-10 relative is ~1e5 x tighter than any gate or misfit test needs
(the Birge ratio it is compared with scatters by sqrt(2 / nu)), and ~1e3 x looser than the
Newton iteration's stopping rule, so float64 rounding cannot make it flaky."""
import numpy as np
import pytest
from scipy.stats import chi2

from nlos_cl.core.errors import InputError
from nlos_cl.core.stats import chi2_quantile


@pytest.mark.parametrize("probability", [1e-3, 0.5, 0.9, 0.99, 0.999, 0.9999])
@pytest.mark.parametrize("dof", [1, 2, 2.5, 3, 6, 30, 100, 1000, 1e4, 1e5])
def test_chi2_quantile_is_scipys(probability, dof):
    assert chi2_quantile(probability, dof) == pytest.approx(chi2.ppf(probability, dof), rel=1e-10)


def test_closed_forms():
    """Two quantiles with a closed form neither implementation shares: dof 2 is exponential,
    dof 1 the square of a normal quantile."""
    assert chi2_quantile(0.999, 2) == pytest.approx(-2 * np.log(1e-3), rel=1e-12)
    assert chi2_quantile(0.9973002039367398, 1) == pytest.approx(9.0, rel=1e-9)  # 3 sigma


@pytest.mark.parametrize("probability, dof", [(0.0, 3), (1.0, 3), (0.5, 0), (0.5, float("inf"))])
def test_bad_arguments_name_the_field(probability, dof):
    with pytest.raises(InputError):
        chi2_quantile(probability, dof)
