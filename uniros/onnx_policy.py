"""An exported policy run by onnxruntime: raw observation in, the env's action out.

This is what ``uniros deploy`` runs on a robot's machine, where torch and Stable-Baselines3 need not be
installed: it imports onnxruntime and numpy only (``pip install 'uniros[deploy]'``). The file is checked
before it is used (size, ONNX, the uniros record of :mod:`uniros.policy_metadata`, the graph's inputs and
output against that record), each problem one :class:`~uniros.policy_metadata.PolicyFileError` line.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from uniros.policy_metadata import ACTION_OUTPUT, METADATA_KEY, PolicyFileError, PolicyMetadata

#: Largest policy file read (bytes): an MLP policy is well under a megabyte.
MAX_POLICY_BYTES = 256 << 20


class OnnxPolicy:
    """A deterministic policy from a ``uniros export`` ONNX file.

    Args:
        path: the ``.onnx`` file.
        threads: onnxruntime's intra-op threads (1: a small MLP runs fastest, and leaves the cores to the
            robot's driver).

    Raises:
        PolicyFileError: missing, too large, not ONNX, without the uniros record, or a graph that does
            not match its record.
    """

    def __init__(self, path: str | os.PathLike[str], *, threads: int = 1) -> None:
        self.path = Path(path)
        where = str(self.path)
        try:
            size = self.path.stat().st_size
        except OSError as exc:
            raise PolicyFileError(f"{where}: no policy file there ({exc.strerror})") from None
        if not self.path.is_file():
            raise PolicyFileError(f"{where} is not a file")
        if size > MAX_POLICY_BYTES:
            raise PolicyFileError(f"{where} is {size:,} bytes, more than a policy's {MAX_POLICY_BYTES:,}")
        try:
            import onnxruntime as ort
        except ImportError as exc:
            raise PolicyFileError(f"running an exported policy needs onnxruntime: pip install 'uniros[deploy]' "
                                  f"({exc})") from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = max(1, int(threads))
        options.inter_op_num_threads = 1
        options.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(self.path.read_bytes(), sess_options=options,
                                                providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own untyped errors for a bad file
            first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else type(exc).__name__
            raise PolicyFileError(f"{where} is not an ONNX model onnxruntime can run ({first})") from None
        props = self.session.get_modelmeta().custom_metadata_map
        if METADATA_KEY not in props:
            raise PolicyFileError(f"{where} is an ONNX model without uniros metadata (export it with "
                                  "`uniros export RUN`)")
        self.metadata = PolicyMetadata.from_json(props[METADATA_KEY], where)
        self._check_graph(where)
        self._names = [i.name for i in self.metadata.inputs]
        self._dtypes = [np.dtype(i.dtype) for i in self.metadata.inputs]
        self._shapes = [i.shape for i in self.metadata.inputs]

    def _check_graph(self, where: str) -> None:
        graph_inputs = self.session.get_inputs()
        names = [i.name for i in graph_inputs]
        wanted = [i.name for i in self.metadata.inputs]
        if names != wanted:
            raise PolicyFileError(f"{where}: the graph's inputs {names[:8]} are not the metadata's {wanted[:8]}")
        for graph_input, meta in zip(graph_inputs, self.metadata.inputs):
            if list(graph_input.shape[1:]) != list(meta.shape):
                raise PolicyFileError(f"{where}: input {meta.name!r} has the shape {graph_input.shape} in the graph, "
                                      f"(batch, {', '.join(map(str, meta.shape))}) in the metadata")
        outputs = [o.name for o in self.session.get_outputs()]
        if outputs != [ACTION_OUTPUT]:
            raise PolicyFileError(f"{where}: the graph's outputs are {outputs[:8]}, not [{ACTION_OUTPUT!r}]")

    def feed(self, observation: Any) -> dict[str, np.ndarray]:
        """The graph's inputs for one observation (a batch of one), checked against the metadata's shapes."""
        keys = self.metadata.keys
        if keys is None:
            parts = [observation]
        else:
            if not isinstance(observation, Mapping):
                raise ValueError(f"{self.path.name} takes a dict observation with keys {list(keys)}")
            missing = [k for k in keys if k not in observation]
            if missing:
                raise ValueError(f"the observation lacks {missing} ({self.path.name} takes {list(keys)})")
            parts = [observation[k] for k in keys]
        out = {}
        for name, dtype, shape, part in zip(self._names, self._dtypes, self._shapes, parts):
            array = np.asarray(part, dtype=dtype)
            if array.shape != shape:
                raise ValueError(f"observation {name!r} has the shape {array.shape}, the policy takes {shape}")
            out[name] = array[None]
        return out

    def act(self, observation: Any) -> np.ndarray:
        """The action for one observation (the env's raw observation; the graph normalises it)."""
        return np.asarray(self.session.run(None, self.feed(observation))[0][0])

    def act_batch(self, inputs: Mapping[str, np.ndarray]) -> np.ndarray:
        """Actions for a batch: ``inputs`` maps each input name to an array with a leading batch dimension."""
        return np.asarray(self.session.run(None, {n: np.asarray(inputs[n], dtype=d)
                                                  for n, d in zip(self._names, self._dtypes)})[0])


__all__ = ["MAX_POLICY_BYTES", "OnnxPolicy"]
