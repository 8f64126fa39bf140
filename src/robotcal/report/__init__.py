"""Report layer: the self-contained HTML report, rendered from a :class:`robotcal.pipeline.RunResult` (above
the pipeline; only ``cli`` and, lazily, the pipeline's last stage import it). The figures it embeds are drawn
by :mod:`robotcal.plots`, below the pipeline."""

from functools import cache

from robotcal._version import installed_version

__all__ = ["installed_version", "template_environment"]


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
