"""``jaxheli report``: one self-contained HTML report of identification results and their gap diagnosis."""

from .build import build_report as build_report, write_report as write_report
from .inputs import DiagnosisSource as DiagnosisSource, ResultSource as ResultSource
from .inputs import load_diagnosis as load_diagnosis, load_flights as load_flights, load_results as load_results
from .sections import SECTION_IDS as SECTION_IDS
