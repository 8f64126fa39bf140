"""The report's sections: one builder per section turns the run (:class:`~robotcal.report.page._Page`) into the
context of its template (``templates/<section>.html.j2``)."""
