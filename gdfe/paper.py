"""The paper's constants and data, in one place (Kwok & Chen 2017, the GDFE paper).

Every study, the benchmark, the command line and the library take these from here.
Lengths in millimetres, angles in radians.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["H", "K", "R_ROUNDED", "FIG6_D", "FIG6_LENGTHS", "FIG6_SIMULATED", "FIG6_EQ1", "FIG6_MAX_ERROR",
           "TABLE1", "TABLE1_R2"]

#: Active-film thickness of all the paper's tests [mm] (stated in the text).
H = 0.29
#: Coefficient K of Eq. 1 as printed.
K = 0.3706
#: The coefficient of determination the paper reports for its fit of Eq. 1 ("around 0.8").
TABLE1_R2 = 0.8
#: The contraction ratio the paper quotes for d = 0.33 mm ("R = 0.7", Eq. 3 rounded).
R_ROUNDED = 0.7
#: Passive-layer thickness of the Figure 6 hinges [mm], also that of the paper's other
#: specimens ("R = 0.7").
FIG6_D = 0.33
#: Hinge widths of Figure 6 [mm].
FIG6_LENGTHS = (1.0, 1.6, 2.6)
#: The paper's own simulated fold angles of the Figure 6 hinges [rad].
FIG6_SIMULATED = (1.04, 1.66, 2.70)
#: Eq. 1's angles of the Figure 6 hinges as the paper prints them [rad].
FIG6_EQ1 = (1.05, 1.68, 2.73)
#: The largest difference between simulation and Eq. 1 the paper reports for Figure 6 [rad].
FIG6_MAX_ERROR = 0.03
#: Table 1 of the paper (18 folding tests: L_mm, d_mm, h_mm, alpha_rad), shipped with the package.
TABLE1 = Path(__file__).resolve().parent / "data" / "table1.csv"
