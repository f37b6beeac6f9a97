!> The element kinds a scene can declare, in one table: for each its class (joint or force;
!> effects that carry states of their own, such as wear, get the third class), its code within
!> the class (the first row of the scene tables jint/fint), its name (the spelling of scene files
!> and of Python), the constraint rows it adds (joints) and the states it carries (effects).
!> mbdk.h mirrors the codes as enums (kernel/tests/c_element_table.c checks them), Python reads
!> the table through the f2py layer (python/mbdk/model.py; tests/test_elements.py checks the
!> scene format against it). The position of a kind in this table is its visit counter
!> (mbdk_model_work_t%visits): the model counts every pass over an element of that kind.
!>
!> Bodies have kinds too, in a table of their own: the coordinates and velocities a body of the
!> kind carries. Planar bodies (x, y, theta) are chapters 2-4 of the book. Spatial bodies
!> (position and Euler parameters, chapter 5) are declared so that scenes, tables and embedders
!> can name them; until their joints, forces and mass matrix exist mbdk_model_init refuses them
!> with MBDK_ERR_NOT_APPLICABLE (available = .false.).
!>
!> Adding a kind: ARCHITECTURE.md at the top of the repository lists the files it touches.
module mbdk_elements
  implicit none
  private
  public :: mbdk_element_kind, mbdk_element_visit, mbdk_joint_rows, mbdk_body_kind

  integer, parameter, public :: MBDK_CLASS_JOINT = 1, MBDK_CLASS_FORCE = 2, MBDK_CLASS_EFFECT = 3

  integer, parameter, public :: MBDK_JOINT_REVOLUTE = 1, MBDK_JOINT_PRISMATIC = 2, &
    MBDK_JOINT_FIXED = 3, MBDK_JOINT_DRIVER = 4, MBDK_JOINT_DISTANCE = 5, &
    MBDK_JOINT_POINT_LINE = 6, MBDK_JOINT_POINT_CURVE = 7, MBDK_JOINT_COUPLING = 8, &
    MBDK_JOINT_ROLLING = 9, MBDK_JOINT_KNIFE_EDGE = 10, MBDK_JOINT_TYPES = 10
  !> spring, damper and spring_damper share the point-to-point geometry; a spring has no
  !> damping, a damper no stiffness (mbdk_model_init refuses tables that say otherwise)
  integer, parameter, public :: MBDK_FORCE_GRAVITY = 1, MBDK_FORCE_POINT = 2, &
    MBDK_FORCE_TORQUE = 3, MBDK_FORCE_SPRING_DAMPER = 4, MBDK_FORCE_COORDINATE = 5, &
    MBDK_FORCE_SPRING = 6, MBDK_FORCE_DAMPER = 7, MBDK_FORCE_CONTACT = 8, &
    MBDK_FORCE_FRICTION = 9, MBDK_FORCE_TYPES = 9
  !> effects share the force table (fint, freal) and continue its codes, so that a scene's
  !> element columns stay one table and a kind's visit counter is MBDK_JOINT_TYPES + code
  integer, parameter, public :: MBDK_EFFECT_WEAR = 10, MBDK_EFFECT_TYPES = 1
  integer, parameter, public :: MBDK_ELEMENT_KINDS = MBDK_JOINT_TYPES + MBDK_FORCE_TYPES + &
    MBDK_EFFECT_TYPES
  !> constraint rows by joint type: a named constant, so that the joints' evaluation (another
  !> module, called for every joint at every evaluation) reads it inline instead of calling
  !> mbdk_joint_rows
  integer, parameter, public :: MBDK_JOINT_ROW_COUNT(MBDK_JOINT_TYPES) = &
    [2, 2, 3, 1, 1, 1, 1, 1, 2, 1]
  integer, parameter, public :: MBDK_ELEMENT_NAME_LEN = 32

  integer, parameter, public :: MBDK_BODY_PLANAR = 1, MBDK_BODY_SPATIAL = 2, MBDK_BODY_KINDS = 2
  !> coordinates of a planar body, which the joints and forces index as 3 b - 2 .. 3 b
  integer, parameter, public :: MBDK_PLANAR_COORDS = 3

  type :: body_entry
    integer :: code
    character(len=MBDK_ELEMENT_NAME_LEN) :: name
    integer :: coords, velocities
    logical :: available
  end type body_entry

  type(body_entry), parameter :: bodies(MBDK_BODY_KINDS) = [ &
    body_entry(MBDK_BODY_PLANAR, 'planar', MBDK_PLANAR_COORDS, MBDK_PLANAR_COORDS, .true.), &
    body_entry(MBDK_BODY_SPATIAL, 'spatial', 7, 6, .false.) ]

  type :: kind_entry
    integer :: cls, code
    character(len=MBDK_ELEMENT_NAME_LEN) :: name
    integer :: rows, states
  end type kind_entry

  type(kind_entry), parameter :: table(MBDK_ELEMENT_KINDS) = [ &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_REVOLUTE, 'revolute', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_REVOLUTE), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_PRISMATIC, 'prismatic', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_PRISMATIC), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_FIXED, 'fixed', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_FIXED), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_DRIVER, 'driver', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_DRIVER), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_DISTANCE, 'distance', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_DISTANCE), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_POINT_LINE, 'point_line', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_POINT_LINE), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_POINT_CURVE, 'point_curve', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_POINT_CURVE), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_COUPLING, 'coupling', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_COUPLING), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_ROLLING, 'rolling', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_ROLLING), 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_KNIFE_EDGE, 'knife_edge', &
               MBDK_JOINT_ROW_COUNT(MBDK_JOINT_KNIFE_EDGE), 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_GRAVITY, 'gravity', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_POINT, 'point_force', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_TORQUE, 'torque', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPRING_DAMPER, 'spring_damper', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_COORDINATE, 'coordinate_spring_damper', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPRING, 'spring', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_DAMPER, 'damper', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_CONTACT, 'contact', 0, 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_FRICTION, 'friction', 0, 0), &
    kind_entry(MBDK_CLASS_EFFECT, MBDK_EFFECT_WEAR, 'wear', 0, 1) ]

contains

  !> Entry i (1-based) of the table; cls = 0 past the end.
  pure subroutine mbdk_element_kind(i, cls, code, name, rows, states)
    integer, intent(in) :: i
    integer, intent(out) :: cls, code, rows, states
    character(len=*), intent(out) :: name
    cls = 0; code = 0; rows = 0; states = 0; name = ''
    if (i < 1 .or. i > MBDK_ELEMENT_KINDS) return
    cls = table(i)%cls
    code = table(i)%code
    name = table(i)%name
    rows = table(i)%rows
    states = table(i)%states
  end subroutine mbdk_element_kind

  !> Entry i (1-based) of the body kinds; code = 0 past the end.
  pure subroutine mbdk_body_kind(i, code, name, coords, velocities, available)
    integer, intent(in) :: i
    integer, intent(out) :: code, coords, velocities
    character(len=*), intent(out) :: name
    logical, intent(out) :: available
    code = 0; coords = 0; velocities = 0; name = ''; available = .false.
    if (i < 1 .or. i > MBDK_BODY_KINDS) return
    code = bodies(i)%code
    name = bodies(i)%name
    coords = bodies(i)%coords
    velocities = bodies(i)%velocities
    available = bodies(i)%available
  end subroutine mbdk_body_kind

  !> The visit counter of a kind: its position in the table (joints first, then forces).
  pure integer function mbdk_element_visit(cls, code)
    integer, intent(in) :: cls, code
    mbdk_element_visit = code
    if (cls == MBDK_CLASS_FORCE .or. cls == MBDK_CLASS_EFFECT) &
      mbdk_element_visit = MBDK_JOINT_TYPES + code
  end function mbdk_element_visit

  !> Constraint rows of a joint type (0 for an unknown type).
  pure integer function mbdk_joint_rows(jtype)
    integer, intent(in) :: jtype
    mbdk_joint_rows = 0
    if (jtype >= 1 .and. jtype <= MBDK_JOINT_TYPES) mbdk_joint_rows = MBDK_JOINT_ROW_COUNT(jtype)
  end function mbdk_joint_rows

end module mbdk_elements
