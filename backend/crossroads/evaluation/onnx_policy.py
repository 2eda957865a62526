"""ONNX policies (``--policy onnx:PATH.onnx``): a network from any training tool, run by onnxruntime.

The contract, checked when the file is loaded (:func:`inspect_onnx`, then a trial run):

* one input, float32 or float64, shape ``(batch, 108)``: the IDC state of one candidate path per
  row, the layout of :mod:`crossroads.idc.state` (x_ego 8, x_track 4, 8 vehicles + 4 cyclists +
  4 pedestrians × 6, world frame, raw: no normalisation), or ``(batch, 120)``: the same followed by
  the documented path preview. ``batch`` may be symbolic (every candidate in one run) or 1;
* an output ``action`` (or the model's only output) of shape ``(batch, 2)``: [Δδ rad/s, Δa m/s³]
  (clipped to ±0.4 and ±4.5 by the ego model, as every action is);
* optionally an output ``value`` of shape ``(batch,)`` or ``(batch, 1)``: the value of following
  each row's path, lower is better (the IDC's v_w). The controller drives the path of least
  value; without one, the path nearest the ego (least √(Δx² + Δy²) of x_track; ties: the first),
  as the Gymnasium environment's observation tracks by default.

The speed mode (pass/stop, which sets Δv in x_track) comes from the traffic-light logic, as for the
shipped networks: the controller is :class:`~crossroads.idc.decision.IdcController` with the ONNX
graph in place of the torch networks, so ``+shield`` works alike. The file is parsed by ``onnx``
(protobuf, never unpickled), checked by ``onnx.checker`` and executed by onnxruntime only; tensors
kept in external files are refused (a model could name any file of the machine as one).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crossroads.constants import PREVIEW_DIM, STATE_DIM
from crossroads.idc.state import DX, DY, pad_participant

ACTION_OUTPUT = "action"
VALUE_OUTPUT = "value"
ACTION_DIM = 2
STATE_WIDTHS = {STATE_DIM: False, STATE_DIM + PREVIEW_DIM: True}  # input width → reads the path preview
_FLOAT, _DOUBLE = 1, 11  # onnx.TensorProto.FLOAT, DOUBLE
_DTYPES = {_FLOAT: np.float32, _DOUBLE: np.float64}
TRIAL_ROWS = 3  # states of the trial run at load time


class OnnxError(ValueError):
    """The file is not an ONNX policy Crossroads can drive with (the message says why)."""


@dataclass(frozen=True)
class OnnxSignature:
    """What :func:`inspect_onnx` found: the input and outputs the controller uses."""

    input_name: str
    state_width: int  # 108, or 120 with the path preview
    dtype: type[np.floating[Any]]
    batched: bool  # False: the batch dimension is fixed at 1 (one run per candidate)
    action_output: str
    value_output: str | None
    opset: int

    @property
    def preview(self) -> bool:
        return STATE_WIDTHS[self.state_width]

    def to_json(self) -> dict[str, Any]:
        return {"input": self.input_name, "state_width": self.state_width,
                "dtype": np.dtype(self.dtype).name, "batched": self.batched,
                "action_output": self.action_output, "value_output": self.value_output,
                "opset": self.opset}


def _dims(value_info: Any) -> list[int | str | None]:
    """The shape of a graph input/output: ints, symbolic names, None for unknown."""
    tensor = value_info.type.tensor_type
    if not tensor.HasField("shape"):
        return []
    return [d.dim_value if d.HasField("dim_value") else (d.dim_param or None) for d in tensor.shape.dim]


def _shape_text(dims: list[int | str | None]) -> str:
    return "(" + ", ".join("?" if d is None else str(d) for d in dims) + ")"


def inspect_onnx(data: bytes) -> OnnxSignature:
    """Parse (protobuf) and check (``onnx.checker``) a model, and match its input and outputs
    against the state layout and the action (module docstring). Runs nothing."""
    import onnx
    from google.protobuf.message import DecodeError

    try:
        model = onnx.load_model_from_string(data)
    except (DecodeError, ValueError, RuntimeError) as exc:
        raise OnnxError(f"not an ONNX model ({type(exc).__name__}: {exc})") from None
    if any(t.data_location == onnx.TensorProto.EXTERNAL for t in model.graph.initializer):
        raise OnnxError("the model keeps tensors in external files; save it with the tensors inside "
                        "(onnx.save(model, path, save_as_external_data=False))")
    try:
        onnx.checker.check_model(model)
    except onnx.checker.ValidationError as exc:
        raise OnnxError(f"onnx.checker refused the model: {str(exc).splitlines()[0]}") from None
    initializers = {t.name for t in model.graph.initializer}
    inputs = [i for i in model.graph.input if i.name not in initializers]
    if len(inputs) != 1:
        raise OnnxError(f"the model takes {len(inputs)} inputs ({', '.join(i.name for i in inputs)}); "
                        f"a policy takes one: the IDC state, shape (batch, {STATE_DIM})")
    state = inputs[0]
    elem = state.type.tensor_type.elem_type
    if elem not in _DTYPES:
        raise OnnxError(f"input {state.name!r}: element type {onnx.TensorProto.DataType.Name(elem)}; "
                        "a policy takes float (float32) or double (float64) states")
    dims = _dims(state)
    widths = " or ".join(str(w) for w in STATE_WIDTHS)
    if len(dims) != 2 or dims[1] not in STATE_WIDTHS:
        raise OnnxError(f"input {state.name!r} has shape {_shape_text(dims)}; the IDC state is "
                        f"(batch, {widths}): {STATE_DIM} values (8 ego + 4 tracking + 96 others), "
                        f"or {STATE_DIM + PREVIEW_DIM} with the path preview (crossroads.idc.state)")
    if isinstance(dims[0], int) and dims[0] not in (0, 1):
        raise OnnxError(f"input {state.name!r} has a fixed batch of {dims[0]}; use a symbolic batch "
                        "dimension (or 1): the number of candidate paths varies")
    outputs = {o.name: o for o in model.graph.output}
    if ACTION_OUTPUT in outputs:
        action = outputs[ACTION_OUTPUT]
    elif len(outputs) == 1:
        action = next(iter(outputs.values()))
    else:
        raise OnnxError(f"the model has outputs {', '.join(outputs)}; name the action output "
                        f"{ACTION_OUTPUT!r} (and the optional path value {VALUE_OUTPUT!r})")
    action_dims = _dims(action)
    fixed_width = action_dims[1] if len(action_dims) == 2 and isinstance(action_dims[1], int) else None
    if len(action_dims) != 2 or fixed_width not in (None, ACTION_DIM):
        raise OnnxError(f"output {action.name!r} has shape {_shape_text(action_dims)}; the action is "
                        f"(batch, {ACTION_DIM}): [Δδ rad/s, Δa m/s³]")
    value = outputs.get(VALUE_OUTPUT) if action.name != VALUE_OUTPUT else None
    if value is not None:
        value_dims = _dims(value)
        if not (len(value_dims) == 1 or (len(value_dims) == 2 and value_dims[1] in (1, None))):
            raise OnnxError(f"output {value.name!r} has shape {_shape_text(value_dims)}; the path "
                            "value is (batch,) or (batch, 1)")
    opset = max((o.version for o in model.opset_import if o.domain in ("", "ai.onnx")), default=0)
    return OnnxSignature(state.name, int(dims[1]), _DTYPES[elem], not isinstance(dims[0], int) or dims[0] == 0,
                         action.name, None if value is None else value.name, opset)


def trial_states(width: int, rows: int = TRIAL_ROWS) -> np.ndarray:
    """``rows`` plausible states of an ego on an empty road (every participant slot padded, some
    tracking error): what the trial run at load time feeds a model."""
    ego = np.array([0.0, 0.0, 8.0, 0.0, np.pi / 2, 0.0, 0.0, 0.0])
    pad = pad_participant(ego)
    out = np.zeros((rows, width))
    out[:, :8] = ego
    out[:, 12:STATE_DIM] = np.tile(pad, (STATE_DIM - 12) // 6)
    out[:, DY] = np.linspace(-1.0, 1.0, rows)
    return out


class OnnxNetworks:
    """An onnxruntime session over a checked model: actions and values of batches of states."""

    def __init__(self, data: bytes, *, source: str = "model", threads: int = 1) -> None:
        import onnxruntime as ort

        self.signature = inspect_onnx(data)
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads  # a batch worker drives on one core
        options.inter_op_num_threads = 1
        options.log_severity_level = 3  # errors only
        try:
            self.session = ort.InferenceSession(data, sess_options=options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own types
            raise OnnxError(f"onnxruntime cannot run the model: {str(exc).splitlines()[0]}") from None
        self._check(source)

    def _run(self, output: str, states: np.ndarray) -> np.ndarray:
        sig = self.signature
        x = np.ascontiguousarray(states, dtype=sig.dtype)
        if sig.batched:
            return np.asarray(self.session.run([output], {sig.input_name: x})[0])
        return np.concatenate([np.asarray(self.session.run([output], {sig.input_name: x[k:k + 1]})[0])
                               for k in range(len(x))])

    def actions(self, states: np.ndarray) -> np.ndarray:
        """(n, 2) actions of (n, width) states."""
        return self._run(self.signature.action_output, states).reshape(len(states), ACTION_DIM)

    def values(self, states: np.ndarray) -> np.ndarray | None:
        """(n,) path values of (n, width) states; None when the model has no value output."""
        if self.signature.value_output is None:
            return None
        return self._run(self.signature.value_output, states).reshape(len(states))

    def _check(self, source: str) -> None:
        """Run the model once on :func:`trial_states`: the outputs must have the declared shapes
        and be finite (symbolic output shapes are only known by running)."""
        states = trial_states(self.signature.state_width)
        try:
            action = self._run(self.signature.action_output, states)
            value = (None if self.signature.value_output is None
                     else self._run(self.signature.value_output, states))
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own types
            raise OnnxError(f"{source} fails on a trial state: {str(exc).splitlines()[0]}") from None
        if action.shape != (len(states), ACTION_DIM):
            raise OnnxError(f"{source}: output {self.signature.action_output!r} gave shape {action.shape} "
                            f"for {len(states)} states; expected ({len(states)}, {ACTION_DIM})")
        if value is not None and value.size != len(states):
            raise OnnxError(f"{source}: output {self.signature.value_output!r} gave shape {value.shape} "
                            f"for {len(states)} states; expected ({len(states)},)")
        if not np.isfinite(action).all() or (value is not None and not np.isfinite(value).all()):
            raise OnnxError(f"{source} gives non-finite outputs on a trial state")


def nearest_path_values(states: np.ndarray) -> np.ndarray:
    """√(Δx² + Δy²) of each state's x_track: the distance to its path, the "value" of a policy
    without one (the nearest path is driven)."""
    return np.hypot(states[:, DX], states[:, DY])


def _torch_modules(networks: OnnxNetworks) -> tuple[Any, Any]:
    """The ONNX graph as the two torch modules :class:`~crossroads.idc.decision.IdcController`
    drives with (a policy with ``mean_action`` and ``preview``, a value network)."""
    import torch
    from torch import nn

    dtype = torch.float64 if networks.signature.dtype is np.float64 else torch.float32

    class _Base(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            # no weights of its own: the parameter only tells IdcController the dtype to feed
            self.dtype_marker = nn.Parameter(torch.zeros(0, dtype=dtype), requires_grad=False)

    class OnnxPolicy(_Base):
        preview = networks.signature.preview

        def mean_action(self, states: torch.Tensor) -> torch.Tensor:
            return torch.from_numpy(networks.actions(states.numpy()).astype(np.float64))

    class OnnxValue(_Base):
        def forward(self, states: torch.Tensor) -> torch.Tensor:
            x = states.numpy()
            values = networks.values(x)
            return torch.from_numpy((nearest_path_values(x) if values is None else values).astype(np.float64))

    return OnnxPolicy(), OnnxValue()


def load_onnx_controller(path: Path, *, name: str, shield: bool = False) -> Any:
    """The IDC controller driven by the ONNX policy in ``path`` (checked first; :class:`OnnxError`)."""
    from crossroads.idc.decision import IdcController

    networks = OnnxNetworks(Path(path).read_bytes(), source=str(path))
    policy, value = _torch_modules(networks)
    controller = IdcController(policy, value, name=name, shield=shield)
    controller.onnx_signature = networks.signature  # type: ignore[attr-defined]
    return controller
