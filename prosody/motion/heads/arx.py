"""The ARX head-motion model of docs/models.md: head pitch, yaw and roll from speech.

    y[t] = sum_{i=1..na} A_i y[t-i] + sum_{j=0..nb-1} B_j u[t-nk-j] + c

y holds FAP 48, 49, 50 (divided by their training spread), u the normalised audio inputs: energy,
conditioned F0, their product, and both averaged over the last second. By default each recording's inputs
are first standardised over that recording (zero mean, unit spread), which takes out its recording level
and the speaker's pitch range: without it, models trained on some speakers gave yaw and roll that were
anti-correlated with held-out speakers' motion. The coefficients come from one
ridge-regularised least-squares fit (numpy) over all training recordings, with regressors never crossing
from one recording into the next; generation runs the model free, feeding back its own predictions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from audio_features import DEFAULT_FPS, Features

from ...errors import ConfigError, ModelError
from ...fap.table import HEAD_FAPS
from ..model_files import MODELS_DIR, JsonModel, TrainingClip, model_array, model_payload

MODEL_FORMAT = "visual-prosody-arx"
MODEL_VERSION = 1
INPUT_NAMES = ("energy_db", "f0_conditioned_hz", "energy_x_f0", "energy_db_mean_1s", "f0_conditioned_hz_mean_1s")
#: Largest spectral radius accepted for the free-running model (1 would not decay).
MAX_SPECTRAL_RADIUS = 0.995
DEFAULT_MODEL_PATH = MODELS_DIR / "default_arx.json"
#: Largest ridge penalty (it is raised tenfold until the model is stable: far below overflow).
MAX_RIDGE = 1e6
#: Default orders and ridge penalty of the ARX model (the model, training and the command share them).
DEFAULT_NA, DEFAULT_NB, DEFAULT_NK, DEFAULT_RIDGE = 1, 5, 0, 0.1
ARX_DEFAULTS = {"na": DEFAULT_NA, "nb": DEFAULT_NB, "nk": DEFAULT_NK, "ridge": DEFAULT_RIDGE}


def trailing_mean(values: np.ndarray, window: int) -> np.ndarray:
    """Mean of the last ``window`` frames up to and including each frame (fewer at the start).

    Examples
    --------
    >>> trailing_mean(np.array([1.0, 2.0, 3.0, 4.0]), 2).tolist()
    [1.0, 1.5, 2.5, 3.5]
    """
    cumulative = np.concatenate([[0.0], np.cumsum(values)])
    index = np.arange(values.shape[0])
    start = np.maximum(0, index + 1 - window)
    return (cumulative[index + 1] - cumulative[start]) / (index + 1 - start)


def arx_inputs(features: Features, *, smoothing_s: float = 1.0) -> np.ndarray:
    """The five raw ARX inputs per frame, shape (n_frames, 5), in the order of :data:`INPUT_NAMES`."""
    energy = features.energy.values
    f0 = features.f0_conditioned.values
    window = max(1, int(round(smoothing_s * features.fps)))  # 1 s = 30 frames at 30 fps
    return np.column_stack([energy, f0, energy * f0, trailing_mean(energy, window), trailing_mean(f0, window)])


def _lagged(inputs: np.ndarray, outputs: np.ndarray | None, *, na: int, nb: int, nk: int) -> np.ndarray:
    """Regressor rows [y[t-1..t-na], u[t-nk..t-nk-nb+1], 1] for every t of one recording (zeros before 0)."""
    n, n_inputs = inputs.shape
    columns = []
    if outputs is not None:
        for i in range(1, na + 1):
            shifted = np.zeros_like(outputs)
            shifted[i:] = outputs[: n - i] if i < n else 0.0
            columns.append(shifted)
    for j in range(nb):
        lag = nk + j
        shifted = np.zeros((n, n_inputs))
        if lag < n:
            shifted[lag:] = inputs[: n - lag]
        columns.append(shifted)
    columns.append(np.ones((n, 1)))
    return np.hstack(columns)


def companion_poles(a_matrices: np.ndarray) -> np.ndarray:
    """Eigenvalues of the companion matrix of ``y[t] = sum A_i y[t-i]`` (empty without feedback)."""
    na, k, _ = a_matrices.shape
    if na == 0:
        return np.zeros(0, dtype=complex)
    companion = np.zeros((na * k, na * k))
    companion[:k, :] = np.hstack(list(a_matrices))
    companion[k:, :-k] = np.eye((na - 1) * k)
    return np.linalg.eigvals(companion)


def spectral_radius(a_matrices: np.ndarray) -> float:
    """Largest eigenvalue modulus of the companion matrix of ``y[t] = sum A_i y[t-i]``."""
    poles = companion_poles(a_matrices)
    return float(np.max(np.abs(poles))) if poles.size else 0.0


class ArxHeadModel(JsonModel):
    """Linear ARX model from audio features to head pitch, yaw and roll (FAP 48-50, AU).

    Parameters
    ----------
    na : int >= 0
        Number of past outputs fed back.
    nb : int >= 1
        Number of input lags.
    nk : int >= 0
        Input delay in frames.
    ridge : float >= 0
        Ridge penalty on the (normalised) coefficients; raised automatically (x10 steps) until the
        model is stable when run free.
    smoothing_s : float > 0, in s
        Window of the moving averages among the inputs (1 s: 30 frames at 30 fps).
    input_normalization : {"recording", "global"}
        "recording" standardises each recording's inputs over that recording before the global
        normalisation; "global" uses the training set's mean and spread only.

    Attributes
    ----------
    a_ : array (na, 3, 3), b_ : array (nb, 3, 5), c_ : array (3,)
        Coefficients on normalised data.
    input_mean_, input_std_ : arrays (5,)
        Input normalisation.
    output_scale_ : array (3,)
        AU per unit of normalised output.
    spectral_radius_ : float
        Stability margin of the fitted model (< 1).
    ridge_ : float
        Ridge penalty actually used.
    training_ : list of TrainingClip
    fps_ : float
    """

    #: The name model files and ``--model`` use for this kind.
    kind = "arx"

    def __init__(self, na: int = DEFAULT_NA, nb: int = DEFAULT_NB, nk: int = DEFAULT_NK, ridge: float = DEFAULT_RIDGE,
                 smoothing_s: float = 1.0,
                 input_normalization: str = "recording"):
        self.na = na
        self.nb = nb
        self.nk = nk
        self.ridge = ridge
        self.smoothing_s = smoothing_s
        self.input_normalization = input_normalization

    def _per_recording(self, inputs: np.ndarray) -> np.ndarray:
        if self.input_normalization == "global":
            return inputs
        spread = inputs.std(axis=0)
        return (inputs - inputs.mean(axis=0)) / np.where(spread > 1e-12, spread, 1.0)

    def _check_orders(self) -> None:
        for name, value, low in (("na", self.na, 0), ("nb", self.nb, 1), ("nk", self.nk, 0)):
            if not (isinstance(value, (int, np.integer)) and value >= low):
                raise ConfigError(f"{name} must be a whole number >= {low}, got {value!r}", parameter=name)
        if not (math.isfinite(self.ridge) and 0 <= self.ridge <= MAX_RIDGE):
            raise ConfigError(f"ridge must be a number in [0, {MAX_RIDGE:g}], got {self.ridge!r}")
        if not (math.isfinite(self.smoothing_s) and 0 < self.smoothing_s <= 60):
            raise ConfigError(f"smoothing_s must be a number of seconds in (0, 60], got {self.smoothing_s!r}")
        if self.input_normalization not in ("recording", "global"):
            raise ConfigError(f"input_normalization must be 'recording' or 'global', got {self.input_normalization!r}")

    # fitting --------------------------------------------------------------------------------------------
    def fit_arrays(self, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], *, fps: float = DEFAULT_FPS,
                   names: Sequence[str] | None = None, sources: Sequence[str | None] | None = None) -> ArxHeadModel:
        """Fit on raw input arrays (n_t, n_inputs) and outputs (n_t, n_outputs), one pair per recording
        (``sources``: their audio files, whose SHA-256 the model records)."""
        self._check_orders()
        if len(inputs) != len(outputs) or not inputs:
            raise ConfigError("need the same, non-zero number of input and output recordings")
        for u, y in zip(inputs, outputs, strict=False):
            if u.shape[0] != y.shape[0]:
                raise ConfigError(f"a recording has {u.shape[0]} input frames but {y.shape[0]} output frames")
            if np.ndim(u) != 2 or np.shape(u)[1] != len(INPUT_NAMES) or np.ndim(y) != 2 or np.shape(y)[1] != 3:
                raise ConfigError(f"inputs must be (n, {len(INPUT_NAMES)}) ({', '.join(INPUT_NAMES)}) and outputs "
                                  f"(n, 3) (FAP 48-50), got {np.shape(u)!r} and {np.shape(y)!r}: a model file "
                                  "holds these widths")
        inputs = [self._per_recording(np.asarray(u, float)) for u in inputs]
        stacked_u = np.vstack(inputs)
        stacked_y = np.vstack(outputs)
        self.input_mean_ = stacked_u.mean(axis=0)
        self.input_std_ = np.where(stacked_u.std(axis=0) > 1e-12, stacked_u.std(axis=0), 1.0)
        self.output_scale_ = np.where(stacked_y.std(axis=0) > 1e-12, stacked_y.std(axis=0), 1.0)
        start = max(self.na, self.nk + self.nb - 1)
        rows, targets = [], []
        for u, y in zip(inputs, outputs, strict=False):
            un = (u - self.input_mean_) / self.input_std_
            yn = y / self.output_scale_
            regressors = _lagged(un, yn, na=self.na, nb=self.nb, nk=self.nk)
            rows.append(regressors[start:])
            targets.append(yn[start:])
        x = np.vstack(rows)
        target = np.vstack(targets)
        if x.shape[0] < x.shape[1]:
            raise ConfigError(f"{x.shape[0]} usable frames cannot fit {x.shape[1]} coefficients per axis")
        n_out, n_in = target.shape[1], stacked_u.shape[1]
        ridge = self.ridge
        penalty = np.eye(x.shape[1])[:-1]  # the constant is not shrunk
        for _ in range(12):
            # ridge as extra rows of a least-squares problem: better conditioned than the normal equations
            shrink = np.sqrt(ridge * x.shape[0]) * penalty
            theta = np.linalg.lstsq(np.vstack([x, shrink]), np.vstack([target, np.zeros((shrink.shape[0], n_out))]),
                                    rcond=None)[0]
            a = theta[: self.na * n_out].reshape(self.na, n_out, n_out).transpose(0, 2, 1)
            radius = spectral_radius(a)
            if radius < MAX_SPECTRAL_RADIUS:
                break
            ridge = max(ridge * 10, 1e-4)  # regularise until the free-running model decays
        else:
            raise ModelError(f"no stable ARX model found (spectral radius {radius:.4f} even with ridge {ridge:g})")
        b = theta[self.na * n_out : -1].reshape(self.nb, n_in, n_out).transpose(0, 2, 1)
        self.a_, self.b_, self.c_ = a, b, theta[-1]
        self.spectral_radius_ = radius
        self.ridge_ = ridge
        self.fps_ = float(fps)
        names = list(names) if names is not None else [f"recording {i}" for i in range(len(inputs))]
        sources = list(sources) if sources is not None else [None] * len(inputs)
        self.training_ = [TrainingClip.of(name, int(u.shape[0]), fps, source)
                          for name, u, source in zip(names, inputs, sources, strict=False)]
        return self

    def fit(self, features: Sequence[Features], motion_au: Sequence[np.ndarray],
            names: Sequence[str] | None = None) -> ArxHeadModel:
        """Fit on recordings: their features and recorded head motion, shape (n_frames, 3) in AU."""
        rates = {f.fps for f in features}
        if len(rates) != 1:
            raise ConfigError(f"training recordings have different frame rates {sorted(rates)!r}")
        inputs = [arx_inputs(f, smoothing_s=self.smoothing_s) for f in features]
        return self.fit_arrays(inputs, [np.asarray(m, float) for m in motion_au], fps=rates.pop(), names=names,
                               sources=[f.source for f in features])

    def coefficients_in_units(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B, c)`` of ``y[t] = sum A_i y[t-i] + sum B_j u[t-nk-j] + c`` in the data's own units
        (shapes (na, k, k), (nb, k, m), (k,)); defined for ``input_normalization="global"`` only."""
        self._check_fitted()
        if self.input_normalization != "global":
            raise ConfigError("raw-unit coefficients exist only for input_normalization='global'")
        scale = self.output_scale_
        a = scale[None, :, None] * self.a_ / scale[None, None, :]
        b = scale[None, :, None] * self.b_ / self.input_std_[None, None, :]
        c = scale * (self.c_ - sum(bj @ (self.input_mean_ / self.input_std_) for bj in self.b_))
        return a, b, c

    # generation -----------------------------------------------------------------------------------------
    def _exogenous(self, inputs: np.ndarray) -> np.ndarray:
        un = (inputs - self.input_mean_) / self.input_std_
        regressors = _lagged(un, None, na=0, nb=self.nb, nk=self.nk)
        weights = np.vstack([np.hstack(list(self.b_)).T, self.c_[None, :]])
        return regressors @ weights

    def simulate_arrays(self, inputs: np.ndarray) -> np.ndarray:
        """Free-run output for raw inputs (n, n_inputs): past predictions are fed back, starting from rest."""
        drive = self._exogenous(self._per_recording(np.asarray(inputs, float)))
        n, k = drive.shape
        out = np.zeros((n, k))
        if self.na == 0:
            out = drive
        else:
            stacked_a = np.hstack(list(self.a_))  # (k, na*k)
            history = np.zeros(self.na * k)
            for t in range(n):
                y = stacked_a @ history + drive[t]
                out[t] = y
                history = np.concatenate([y, history[:-k]])
        return out * self.output_scale_

    def one_step_residuals(self, inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
        """Residuals (n, 3) of the fitted regression on one recording: recorded outputs (AU) less the one-step
        prediction from the recorded past outputs and the inputs, in units of the training spread."""
        self._check_fitted()
        un = (self._per_recording(np.asarray(inputs, float)) - self.input_mean_) / self.input_std_
        yn = np.asarray(outputs, float) / self.output_scale_
        regressors = _lagged(un, yn, na=self.na, nb=self.nb, nk=self.nk)
        theta = np.vstack([*(a.T for a in self.a_), *(b.T for b in self.b_), self.c_[None, :]])
        start = max(self.na, self.nk + self.nb - 1)
        return (yn - regressors @ theta)[start:]

    def poles(self) -> np.ndarray:
        """Eigenvalues of the free run's companion matrix (all inside the unit circle for a stable model)."""
        self._check_fitted()
        return companion_poles(self.a_)

    #: The same motion for every seed (the model is a deterministic free run).
    stochastic: ClassVar[bool] = False

    def rest_pose_au(self) -> np.ndarray:
        """The pose the model settles to when every input sits at its recording's average (per-recording
        normalisation) or at the training average ("global"): the steady state of the free run, AU (3,).
        Intensity gains scale the motion about this pose, not about 0."""
        self._check_fitted()
        level = (-self.input_mean_ / self.input_std_ if self.input_normalization == "recording"
                 else np.zeros_like(self.input_mean_))
        drive = sum((bj @ level for bj in self.b_), np.zeros(len(HEAD_FAPS))) + self.c_
        feedback = np.eye(len(HEAD_FAPS)) - (self.a_.sum(axis=0) if self.na else 0.0)
        return np.linalg.solve(feedback, drive) * self.output_scale_

    def generate(self, features: Features, *, seed: int = 0) -> dict[int, np.ndarray]:
        """Head motion for a recording, run free: FAP number (48, 49, 50) -> curve in AU. The model is
        deterministic: ``seed`` is accepted for a common interface with the other head models and unused."""
        self._check_fitted()
        if features.fps != self.fps_:
            raise ConfigError(
                f"the model was trained at {self.fps_:g} fps but the features are at {features.fps:g} fps; "
                "extract features at the model's rate or train a model at this rate"
            )
        motion = self.simulate_arrays(arx_inputs(features, smoothing_s=self.smoothing_s))
        return {fap: motion[:, axis] for axis, fap in enumerate(HEAD_FAPS)}

    def _check_fitted(self) -> None:
        if not hasattr(self, "a_"):
            raise ConfigError("the model is not fitted: call fit() or load a model file")

    # persistence ----------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        self._check_fitted()
        return {
            "format": MODEL_FORMAT,
            "version": MODEL_VERSION,
            "kind": self.kind,
            "orders": {"na": int(self.na), "nb": int(self.nb), "nk": int(self.nk)},
            "fps": self.fps_,
            "smoothing_s": self.smoothing_s,
            "input_normalization": self.input_normalization,
            "inputs": list(INPUT_NAMES),
            "outputs": list(HEAD_FAPS),
            "input_mean": self.input_mean_.tolist(),
            "input_std": self.input_std_.tolist(),
            "output_scale_au": self.output_scale_.tolist(),
            "a": self.a_.tolist(),
            "b": self.b_.tolist(),
            "c": self.c_.tolist(),
            "ridge": self.ridge_,
            "spectral_radius": self.spectral_radius_,
            "training": [clip.__dict__ for clip in self.training_],
        }

    @classmethod
    def from_dict(cls, payload: object, *, source: str = "<dict>") -> ArxHeadModel:
        """Rebuild a model from :meth:`to_dict` output, checking every field."""

        def fail(problem: str) -> ModelError:
            return ModelError(f"{source}: {problem}")

        payload = model_payload(payload, format_name=MODEL_FORMAT, source=source, version=MODEL_VERSION)
        try:
            orders = payload["orders"]
            model = cls(int(orders["na"]), int(orders["nb"]), int(orders["nk"]),
                        ridge=float(payload["ridge"]), smoothing_s=float(payload["smoothing_s"]),
                        input_normalization=str(payload["input_normalization"]))
            try:
                model._check_orders()
            except ConfigError as error:
                raise fail(str(error)) from None
            n_out, n_in = len(HEAD_FAPS), len(INPUT_NAMES)
            fields = {
                "a": (model.na, n_out, n_out), "b": (model.nb, n_out, n_in), "c": (n_out,),
                "input_mean": (n_in,), "input_std": (n_in,), "output_scale_au": (n_out,),
            }
            arrays = {key: model_array(payload, key, shape, fail) for key, shape in fields.items()}
            if np.any(arrays["input_std"] <= 0) or np.any(arrays["output_scale_au"] <= 0):
                raise fail("normalisation scales must be positive")
            if list(payload["inputs"]) != list(INPUT_NAMES) or list(payload["outputs"]) != list(HEAD_FAPS):
                raise fail(f"inputs/outputs must be {list(INPUT_NAMES)} / {list(HEAD_FAPS)}")
            fps = payload["fps"]
            if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps)
                                                                                 and 0 < fps <= 1000):
                raise fail(f"fps {fps!r} must be a number in (0, 1000]")
            fps = float(fps)
            training = [TrainingClip.from_dict(c) for c in payload["training"]]
        except ModelError:
            raise
        except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as error:
            raise fail(f"missing or malformed field ({type(error).__name__}: {error})") from None
        radius = spectral_radius(arrays["a"])
        if radius >= 1.0:
            raise fail(f"the model is unstable when run free (spectral radius {radius:.4f} >= 1)")
        model.a_, model.b_, model.c_ = arrays["a"], arrays["b"], arrays["c"]
        model.input_mean_, model.input_std_ = arrays["input_mean"], arrays["input_std"]
        model.output_scale_ = arrays["output_scale_au"]
        model.spectral_radius_, model.ridge_, model.fps_ = radius, model.ridge, fps
        model.training_ = training
        return model


def default_model() -> ArxHeadModel:
    """The thesis's ARX model as shipped with the package (trained on the seven talking-head clips; see
    docs/evaluation.md). The default speech-driven head is :func:`prosody.motion.heads.models.default_head_model`."""
    return ArxHeadModel.load(DEFAULT_MODEL_PATH)
