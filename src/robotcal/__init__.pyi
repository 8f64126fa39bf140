# The public names of robotcal and the module that defines each: read at run time by lazy_loader (the
# names load on first use) and by type checkers and IDEs. The one list of robotcal's front door.
from .api import calibration_capture as calibration_capture
from .api import change_plan as change_plan
from .api import check_plan as check_plan
from .api import compensate as compensate
from .api import diagnose_joints as diagnose_joints
from .api import evaluate as evaluate
from .api import filter_program as filter_program
from .api import identify as identify
from .api import monte_carlo as monte_carlo
from .api import perturb as perturb
from .api import refine as refine
from .api import simulate as simulate
from .api import simulate_poses as simulate_poses
from .api import tcp_uncertainty as tcp_uncertainty
from .api import validation_consistency as validation_consistency
from .api import workspace_uncertainty as workspace_uncertainty
from .capture import Capture as Capture
from .errors import InputError as InputError
from .errors import RobotcalError as RobotcalError
from .identification.cpa import CPAOptions as CPAOptions
from .identification.targets import Target as Target
from .instruments import Instrument as Instrument
from .io.capture_csv import read_capture as read_capture
from .io.capture_csv import write_capture as write_capture
from .io.parameters_json import read_parameters as read_parameters
from .io.parameters_json import write_parameters as write_parameters
from .io.robots import load_robot as load_robot
from .io.run_folder import RunResult as RunResult
from .io.run_folder import read_run as read_run
from .io.scenario import Scenario as Scenario
from .io.scenario import load_scenario as load_scenario
from .kinematics.joint_model import JointModel as JointModel
from .kinematics.model import LinkMasses as LinkMasses
from .kinematics.model import ParameterSet as ParameterSet
from .kinematics.model import ReflectorMount as ReflectorMount
from .kinematics.model import RobotModel as RobotModel
from .pipeline.plan import plan_run as plan_run
from .pipeline.run import run_calibration as run_calibration
from .report.html import render_report as render_report
from .simulation.plan import CapturePlan as CapturePlan

__version__: str
