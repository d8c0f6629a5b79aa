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
# A numerical floor for divisions, logs and square roots of values that may be 0 (weights, variances,
# energies): far below anything physical, so it changes no value that is not 0.
TINY = 1e-300
# The paper's pulse (70 ps FWHM, Section 4) and a SPAD's timing jitter: the model's defaults.
PAPER_PULSE_FWHM_S = 70e-12
PAPER_PULSE_SIGMA_S = PAPER_PULSE_FWHM_S / FWHM_PER_SIGMA  # 29.73 ps
DEFAULT_JITTER_S = 30e-12
