"""Golden vs candidate bag comparison: pure, no rclpy.

```python
from bagkit.compare import CompareOptions, Tolerance, compare_bags

report = compare_bags(golden, candidate, CompareOptions(tolerance=Tolerance(atol=1e-6)))
report.passed; report.to_dict(); report.first_divergences()
```
"""

from __future__ import annotations

from bagkit.compare.bags import compare_bags, field_series
from bagkit.compare.core import Event, Sample, compare_events, compare_samples
from bagkit.compare.errors import CompareError
from bagkit.compare.options import (
    CompareOptions,
    Tolerance,
    ToleranceRule,
    options_from_mapping,
    replace_options,
)
from bagkit.compare.result import CompareReport, Divergence, FieldResult, TopicResult

__all__ = [
    "CompareError",
    "CompareOptions",
    "CompareReport",
    "Divergence",
    "Event",
    "FieldResult",
    "Sample",
    "Tolerance",
    "ToleranceRule",
    "TopicResult",
    "compare_bags",
    "compare_events",
    "compare_samples",
    "field_series",
    "options_from_mapping",
    "replace_options",
]
