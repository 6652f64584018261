# TEMPORARY re-export for the studies being moved out; removed when branch floors merges
from tavc_env.validation import is_integer as is_integer
from tavc_env.validation import is_number as is_number
from tavc_env.validation import require as require
