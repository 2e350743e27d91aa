"""JSON text as Python data, with one `ValueError` for every way it cannot be read.

`json.loads` fails three ways on a file someone edited or damaged: `json.JSONDecodeError`
(malformed), a `RecursionError` (arrays or objects nested some thousands deep) and a plain
`ValueError` (an integer of more than `sys.get_int_max_str_digits` digits, 4300 by default). Every
reader of a JSON file olatbench or a user writes (transforms files, manifests, results.json,
job.json) parses through `parse_json`, so each says so in one line.
"""

from __future__ import annotations

import json
from typing import Any


def parse_json(text: str) -> Any:
    """``text`` parsed as JSON; a `ValueError` whose message says what is wrong (malformed at
    line/column, nested too deep, a number too long), never a `RecursionError`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(
            f"malformed JSON (line {error.lineno}, column {error.colno}: {error.msg})"
        ) from None
    except RecursionError:
        raise ValueError("malformed JSON (arrays or objects nested too deeply to read)") from None
    # the one other ValueError json raises: an integer longer than Python converts
    except ValueError:
        raise ValueError(
            "malformed JSON (an integer with more digits than Python converts, 4300 by default)"
        ) from None
