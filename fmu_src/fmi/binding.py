"""The FMI version the slaves are bound to (standard library and that version's exporter).

The one place the version-neutral modules of `fmu_src.fmi` name an FMI version: they build on
`Adaptor` and `ModelAdaptor`, FMI 2.0's (`fmu_src.fmi.fmi2.slave`). Another version is a
sibling package whose adaptors offer the same:

- `Adaptor`, the slave base its exporter and runtime take (a slave module's class deepest below
  it is the FMU's), constructed with `instance_name`, `resources` and `visible`;
  `vars` (value reference -> variable: `name`, `local_name`, `getter`, `setter`);
  `declare(value_type, name, causality, variability, description, initial, getter)`,
  `causality_of(var)`, `type_of(var)`, `report(message, status)` in the vocabulary of
  `fmu_src.fmi.vocabulary`; `standard` and `calls`, the names the slaves' messages use;
  pythonfmu's calls the runtime makes by name (`get_integer`, `set_boolean`, ...,
  `_fmu_state_to_bytes`, `_get_log_queue`) and the slave's `log_queue`;
- `ModelAdaptor`, an `Adaptor` whose model description (`to_xml`) is completed from the
  declarations of `fmu_src.fmi.variables.VariableSlave`.
"""

from fmu_src.fmi.fmi2.slave import Fmi2Adaptor as Adaptor
from fmu_src.fmi.fmi2.slave import Fmi2ModelAdaptor as ModelAdaptor

__all__ = ["Adaptor", "ModelAdaptor"]
