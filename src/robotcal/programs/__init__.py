"""Robot programs as the robot runs them (KUKA KRL, ABB RAPID, URScript): read their motion targets, write them back
with new numbers and nothing else changed (issue 28). :mod:`robotcal.programs.base` holds what the readers share."""
