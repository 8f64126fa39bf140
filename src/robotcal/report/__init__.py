"""Report layer: matplotlib figures and the self-contained HTML report (above the pipeline; only ``cli`` and,
lazily, the pipeline's last stage import it)."""

from functools import cache

__all__ = ["template_environment"]


@cache
def template_environment():
    """The Jinja2 environment of the report's templates (``report/templates/``): autoescape on, strict undefined."""
    from jinja2 import Environment, PackageLoader, StrictUndefined

    return Environment(
        loader=PackageLoader("robotcal.report", "templates"),
        autoescape=True,
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
