"""Physical constants and the method's fixed numbers, in one place (SI units)."""
import math

SPEED_OF_LIGHT = 299_792_458.0  # m/s
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))  # a Gaussian's FWHM / sigma
PAPER_H_S = 0.65e-9  # the paper's Gauss filter window h (Section 4)
# Sum-of-logs scoring floors each detector's peak-normalised value here, so one silent
# detector does not make every cell -inf.
LOG_FLOOR = 1e-6
# A joint product (of peak-normalised signals) below this is no signal.
PRODUCT_FLOOR = 1e-30
