!> The element kinds a scene can declare, planar and spatial, in one table: for each its class
!> (joint or force; effects that carry states of their own, such as wear, get the third class),
!> its code within the class (the first row of the planar tables jint/fint, the spatial model's
!> jtype/ftype), its name (the spelling of scene files and of Python), the body kinds it applies
!> to (planar, spatial or both), the constraint rows it adds on each (joints) and the states it
!> carries (effects). A name has one code whichever model runs it: a revolute joint is code 1
!> in a planar scene (2 rows) and in a spatial one (5 rows); the kinds only spatial scenes have
!> continue the codes after the planar ones. mbdk.h mirrors the codes as enums
!> (kernel/tests/c_element_table.c checks them), Python reads the table through the f2py layer
!> (python/mbdk/codes.py; tests/test_elements.py and tests/test_codes.py check the scene formats
!> and both models against it). The position of a kind in this table is its visit counter
!> (mbdk_model_work_t%visits): the planar model counts every pass over an element of that kind.
!>
!> Bodies have kinds too, in a table of their own: the coordinates and velocities a body of the
!> kind carries. Planar bodies (x, y, theta; chapters 2-4 of the book) run in the planar model
!> (mbdk_model), spatial bodies (position and orientation, chapter 5: 7 coordinates with a
!> quaternion, 6 with an angle set) in the spatial model (mbdk_spatial_model). A scene's bodies
!> are of one kind: each model refuses the other's bodies (MBDK_ERR_NOT_APPLICABLE) and takes the
!> element kinds that apply to its own (mbdk_element_applies; MBDK_ERR_INVALID_INPUT for others).
!>
!> Adding a kind: ARCHITECTURE.md at the top of the repository lists the files it touches.
module mbdk_elements
  implicit none
  private
  public :: mbdk_element_kind, mbdk_element_visit, mbdk_element_applies, mbdk_joint_rows, &
    mbdk_body_kind

  integer, parameter, public :: MBDK_CLASS_JOINT = 1, MBDK_CLASS_FORCE = 2, MBDK_CLASS_EFFECT = 3

  integer, parameter, public :: MBDK_BODY_PLANAR = 1, MBDK_BODY_SPATIAL = 2, MBDK_BODY_KINDS = 2
  !> the body kinds an element kind applies to, as bits: bit k - 1 for body kind k
  integer, parameter, public :: MBDK_ON_PLANAR = 1, MBDK_ON_SPATIAL = 2, MBDK_ON_BOTH = 3
  !> coordinates of a planar body, which the joints and forces index as 3 b - 2 .. 3 b
  integer, parameter, public :: MBDK_PLANAR_COORDS = 3

  !> joints: the planar ones, then those of spatial scenes alone (revolute, prismatic and
  !> fixed joints are both models')
  integer, parameter, public :: MBDK_JOINT_REVOLUTE = 1, MBDK_JOINT_PRISMATIC = 2, &
    MBDK_JOINT_FIXED = 3, MBDK_JOINT_DRIVER = 4, MBDK_JOINT_DISTANCE = 5, &
    MBDK_JOINT_POINT_LINE = 6, MBDK_JOINT_POINT_CURVE = 7, MBDK_JOINT_COUPLING = 8, &
    MBDK_JOINT_ROLLING = 9, MBDK_JOINT_KNIFE_EDGE = 10, MBDK_JOINT_SPHERICAL = 11, &
    MBDK_JOINT_UNIVERSAL = 12, MBDK_JOINT_CYLINDRICAL = 13, MBDK_JOINT_ANGLE_DRIVER = 14, &
    MBDK_JOINT_SLIDE_DRIVER = 15, MBDK_JOINT_TYPES = 15
  !> spring, damper and spring_damper share the point-to-point geometry; a spring has no
  !> damping, a damper no stiffness (mbdk_model_init refuses tables that say otherwise).
  !> Gravity, point forces, torques and spring-dampers are both models'; the spatial contacts
  !> continue the codes after the planar ones (and after wear)
  integer, parameter, public :: MBDK_FORCE_GRAVITY = 1, MBDK_FORCE_POINT = 2, &
    MBDK_FORCE_TORQUE = 3, MBDK_FORCE_SPRING_DAMPER = 4, MBDK_FORCE_COORDINATE = 5, &
    MBDK_FORCE_SPRING = 6, MBDK_FORCE_DAMPER = 7, MBDK_FORCE_CONTACT = 8, &
    MBDK_FORCE_FRICTION = 9, MBDK_FORCE_SPHERE_PLANE = 11, MBDK_FORCE_SPHERE_SPHERE = 12
  !> effects share the force table (fint, freal) and its codes, so that a scene's element
  !> columns stay one table and a kind's visit counter is MBDK_JOINT_TYPES + code
  integer, parameter, public :: MBDK_EFFECT_WEAR = 10, MBDK_EFFECT_TYPES = 1
  !> the force table's codes, 1 .. MBDK_FORCE_TYPES: forces and effects
  integer, parameter, public :: MBDK_FORCE_TYPES = 12
  integer, parameter, public :: MBDK_ELEMENT_KINDS = MBDK_JOINT_TYPES + MBDK_FORCE_TYPES
  integer, parameter, public :: MBDK_ELEMENT_NAME_LEN = 32

  type :: body_entry
    integer :: code
    character(len=MBDK_ELEMENT_NAME_LEN) :: name
    integer :: coords, velocities
    logical :: available
  end type body_entry

  type(body_entry), parameter :: bodies(MBDK_BODY_KINDS) = [ &
    body_entry(MBDK_BODY_PLANAR, 'planar', MBDK_PLANAR_COORDS, MBDK_PLANAR_COORDS, .true.), &
    body_entry(MBDK_BODY_SPATIAL, 'spatial', 7, 6, .true.) ]

  type :: kind_entry
    integer :: cls, code
    character(len=MBDK_ELEMENT_NAME_LEN) :: name
    integer :: on                          !< the body kinds it applies to (MBDK_ON_*)
    integer :: rows(MBDK_BODY_KINDS)       !< constraint rows on each body kind (joints)
    integer :: states
  end type kind_entry

  type(kind_entry), parameter :: table(MBDK_ELEMENT_KINDS) = [ &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_REVOLUTE, 'revolute', MBDK_ON_BOTH, [2, 5], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_PRISMATIC, 'prismatic', MBDK_ON_BOTH, [2, 5], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_FIXED, 'fixed', MBDK_ON_BOTH, [3, 6], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_DRIVER, 'driver', MBDK_ON_PLANAR, [1, 0], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_DISTANCE, 'distance', MBDK_ON_PLANAR, [1, 0], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_POINT_LINE, 'point_line', MBDK_ON_PLANAR, [1, 0], &
               0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_POINT_CURVE, 'point_curve', MBDK_ON_PLANAR, &
               [1, 0], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_COUPLING, 'coupling', MBDK_ON_PLANAR, [1, 0], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_ROLLING, 'rolling', MBDK_ON_PLANAR, [2, 0], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_KNIFE_EDGE, 'knife_edge', MBDK_ON_PLANAR, [1, 0], &
               0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_SPHERICAL, 'spherical', MBDK_ON_SPATIAL, [0, 3], &
               0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_UNIVERSAL, 'universal', MBDK_ON_SPATIAL, [0, 4], &
               0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_CYLINDRICAL, 'cylindrical', MBDK_ON_SPATIAL, &
               [0, 4], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_ANGLE_DRIVER, 'angle_driver', MBDK_ON_SPATIAL, &
               [0, 1], 0), &
    kind_entry(MBDK_CLASS_JOINT, MBDK_JOINT_SLIDE_DRIVER, 'slide_driver', MBDK_ON_SPATIAL, &
               [0, 1], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_GRAVITY, 'gravity', MBDK_ON_BOTH, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_POINT, 'point_force', MBDK_ON_BOTH, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_TORQUE, 'torque', MBDK_ON_BOTH, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPRING_DAMPER, 'spring_damper', MBDK_ON_BOTH, &
               [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_COORDINATE, 'coordinate_spring_damper', &
               MBDK_ON_PLANAR, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPRING, 'spring', MBDK_ON_PLANAR, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_DAMPER, 'damper', MBDK_ON_PLANAR, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_CONTACT, 'contact', MBDK_ON_PLANAR, [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_FRICTION, 'friction', MBDK_ON_PLANAR, [0, 0], 0), &
    kind_entry(MBDK_CLASS_EFFECT, MBDK_EFFECT_WEAR, 'wear', MBDK_ON_BOTH, [0, 0], 1), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPHERE_PLANE, 'sphere_plane', MBDK_ON_SPATIAL, &
               [0, 0], 0), &
    kind_entry(MBDK_CLASS_FORCE, MBDK_FORCE_SPHERE_SPHERE, 'sphere_sphere', MBDK_ON_SPATIAL, &
               [0, 0], 0) ]

  !> a planar joint's constraint rows by its code (0 for a joint planar scenes lack): a named
  !> constant, so that the joints' evaluation (another module, called for every joint at every
  !> evaluation) reads it inline instead of calling mbdk_joint_rows
  integer, parameter, public :: MBDK_PLANAR_JOINT_ROWS(MBDK_JOINT_TYPES) = &
    table(1:MBDK_JOINT_TYPES)%rows(MBDK_BODY_PLANAR)

contains

  !> Entry i (1-based) of the table; cls = 0 past the end. on: the body kinds it applies to
  !> (MBDK_ON_*), rows(k): its constraint rows on body kind k (0 where it does not apply).
  pure subroutine mbdk_element_kind(i, cls, code, name, on, rows, states)
    integer, intent(in) :: i
    integer, intent(out) :: cls, code, on, rows(MBDK_BODY_KINDS), states
    character(len=*), intent(out) :: name
    cls = 0; code = 0; on = 0; rows = 0; states = 0; name = ''
    if (i < 1 .or. i > MBDK_ELEMENT_KINDS) return
    cls = table(i)%cls
    code = table(i)%code
    name = table(i)%name
    on = table(i)%on
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

  !> The visit counter of a kind: its position in the table (joints first, then the force
  !> table's codes).
  pure integer function mbdk_element_visit(cls, code)
    integer, intent(in) :: cls, code
    mbdk_element_visit = code
    if (cls == MBDK_CLASS_FORCE .or. cls == MBDK_CLASS_EFFECT) &
      mbdk_element_visit = MBDK_JOINT_TYPES + code
  end function mbdk_element_visit

  !> Whether code is a kind of the joint table (cls = MBDK_CLASS_JOINT) or of the force table
  !> (MBDK_CLASS_FORCE or MBDK_CLASS_EFFECT: forces and effects) that applies to bodies of
  !> kind body; .false. for an unknown code, class or body kind.
  pure logical function mbdk_element_applies(cls, code, body)
    integer, intent(in) :: cls, code, body
    integer :: n
    mbdk_element_applies = .false.
    if (body < 1 .or. body > MBDK_BODY_KINDS) return
    select case (cls)
    case (MBDK_CLASS_JOINT)
      n = MBDK_JOINT_TYPES
    case (MBDK_CLASS_FORCE, MBDK_CLASS_EFFECT)
      n = MBDK_FORCE_TYPES
    case default
      return
    end select
    if (code < 1 .or. code > n) return
    mbdk_element_applies = btest(table(mbdk_element_visit(cls, code))%on, body - 1)
  end function mbdk_element_applies

  !> Constraint rows of a joint type on bodies of kind body (default planar, the planar
  !> model's); 0 for a type that does not apply to them (the table's rows there) or an
  !> unknown one.
  pure integer function mbdk_joint_rows(jtype, body)
    integer, intent(in) :: jtype
    integer, intent(in), optional :: body
    integer :: k
    k = MBDK_BODY_PLANAR
    if (present(body)) k = body
    mbdk_joint_rows = 0
    if (jtype < 1 .or. jtype > MBDK_JOINT_TYPES .or. k < 1 .or. k > MBDK_BODY_KINDS) return
    mbdk_joint_rows = table(jtype)%rows(k)
  end function mbdk_joint_rows

end module mbdk_elements
