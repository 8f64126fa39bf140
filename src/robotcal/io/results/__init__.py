"""Result folders and files: the output-safety policy, run folders and their summary, the files of every stage and
their provenance."""
