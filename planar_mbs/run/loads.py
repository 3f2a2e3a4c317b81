"""A run's own values of its force elements, for `Simulation.set_load` (a controller in the loop).

The compiled model stays read-only: a `Loads` holds this run's copy of the force elements' parameters
and a model that reads them (the same arrays otherwise).  What a force kind lets a controller set is
its catalog entry's ``settable`` columns (`catalog.FORCES`)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import catalog
from ..errors import ModelError, did_you_mean
from ..mechanism.model import Model, read_only


class Loads:
    """This run's force parameters (`set`) and the model the run reads them from (`model`)."""

    def __init__(self, model: Model):
        self.names = list(model.force_names)
        self.param = np.array(model.kernel.force_param, dtype=np.float64)  # this run's, writeable
        self.kinds = [catalog.force_kind(int(c)) for c in model.kernel.force_type]
        self.model = dataclasses.replace(model, kernel=model.kernel._replace(force_param=read_only(self.param)))

    def set(self, name: str, value) -> None:
        """The settable value of force element `name` (SI) for the rest of the run."""
        if name not in self.names:
            raise ModelError(f"no force element `{name}`", "set_load",
                             hint=did_you_mean(name, self.names) or "forces: " + (", ".join(self.names) or "none"))
        k = self.names.index(name)
        spec = self.kinds[k]
        if not spec.settable:
            raise ModelError(f"`{name}` is an element of kind `{spec.name}` ({spec.name} force): it has no value "
                             "to set", "set_load",
                             hint="write the load as a `constant`, `torque` or spring-damper to set it from Python")
        program = spec.program_column(spec.settable[0])
        if program is not None and self.param[k, program] > 0:
            raise ModelError(f"the {spec.settable[0]} of `{name}` is an expression: it has no value to set",
                             "set_load", hint="give it a constant in the model to set it from Python")
        values = np.atleast_1d(np.asarray(value, dtype=float))
        if values.shape != (len(spec.settable),):
            raise ModelError(f"`{name}` takes {len(spec.settable)} value(s) ({', '.join(spec.settable)}), "
                             f"not {values.size}", "set_load", hint="SI values, e.g. set_load(name, 0.3)")
        for column, v in zip(spec.settable, values):
            self.param[k, spec.column(column)] = v
